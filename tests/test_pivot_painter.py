"""Unreal Pivot Painter 2 (core/asset/pivot_painter.py, issue 33), read back the way Epic describes
the textures (Pivot Painter Tool 2.0 and its MAXScript reference): ``pivot_pos_index.exr`` RGB the
pivot (cm, Unreal axes), A the parent index as "Int as float" (the half's bit pattern less 1024; a
root points at itself); ``xaxis_extent.png`` RGB the X axis packed (v+1)/2, A the extent × 2048 cm;
element i at column i mod W, row i div W from the top; each vertex's element at the pixel centre of
its UV channel 1 (V flipped: Unreal's V runs down). Checked on bone budgets of held-out samples and
the full rig of a generated tree: the decoded parents form the rig's branch tree within 4 levels,
the pivots are the bones' heads at rest, the axes and extents their direction and length; the wind
fit recovers a known swing per level; Int-as-float on a hand case."""
import json

import cv2
import numpy as np
import pytest
from exr_reader import rgba
from test_loop import _truth_tree

from tree_from_video import api
from tree_from_video.core import bones
from tree_from_video.core.asset import pivot_painter as ppm
from tree_from_video.core.asset import tree_asset
from tree_from_video.core.asset.rig import BoneKeys, Rig
from tree_from_video.core.rotations import quat_exp


def read_pp2(folder):
    """Epic's description, decoded: ``(pivot (E', 3) cm, parent (E',), axis (E', 3), extent (E',) cm)``
    over every pixel in element order, and the JSON."""
    doc = json.load(open(folder / "pivot_painter.json"))
    pos = rgba(folder / "pivot_pos_index.exr").reshape(-1, 4)
    parent = pos[:, 3].astype(np.float16).view(np.uint16).astype(np.int64) - 1024
    img = cv2.imread(str(folder / "xaxis_extent.png"), cv2.IMREAD_UNCHANGED)[..., [2, 1, 0, 3]].reshape(-1, 4)
    axis = img[:, :3] / 255.0 * 2.0 - 1.0
    extent = img[:, 3] / 255.0 * 2048.0
    return pos[:, :3].astype(np.float64), parent, axis, extent, doc


def element_at_uv(uv: np.ndarray, W: int, H: int) -> np.ndarray:
    """The element a UV 1 (Blender's, V up) points at: Unreal's V = 1 − v runs down the rows."""
    col = np.floor(uv[:, 0] * W).astype(np.int64)
    row = np.floor((1.0 - uv[:, 1]) * H).astype(np.int64)
    return row * W + col


def _check(tree, asset, folder):
    rig = asset.rig
    pp = ppm.pivot_elements(tree, rig)
    ppm.write_pivot_painter(folder, pp)
    pivot, parent, axis, extent, doc = read_pp2(folder)
    E = doc["elements"]
    assert E == len(pp.parent) and doc["width"] * doc["height"] >= E
    pivot, parent, axis, extent = pivot[:E], parent[:E], axis[:E], extent[:E]
    # the parents: roots point at themselves, every chain reaches a root within 3 steps (4 levels)
    assert (parent >= 0).all() and (parent < E).all()
    e = np.arange(E)
    for _ in range(3):
        e = parent[e]
    assert (parent[e] == e).all(), "an element deeper than 4 levels"
    # …and they are the rig's tree: a bone starting an element hangs from its parent bone's element
    elem = pp.element_of_bone
    for b in range(len(rig.names)):
        p = rig.parent[b]
        if p >= 0 and elem[b] != elem[p]:
            assert parent[elem[b]] == elem[p]
        if p < 0:
            assert parent[elem[b]] == elem[b]
    # the pivots are the element's first bone's head at rest (its least deep), cm, Unreal axes (x, −y, z)
    depth = bones.bone_depths(rig.parent)
    first = np.array([min(np.flatnonzero(elem == k), key=lambda b: (depth[b], b)) for k in range(E)])
    want = rig.head[first].astype(np.float64) * [100.0, -100.0, 100.0]
    scale = np.abs(want).max()
    assert np.abs(pivot - want).max() <= 1e-3 * scale + 0.01
    # axes unit within 8-bit steps, pointing up the element (from its pivot towards its bones' tails)
    assert np.abs(np.linalg.norm(axis, axis=1) - 1).max() < 0.02
    tails = rig.tail.astype(np.float64) * [100.0, -100.0, 100.0]
    along = np.einsum("bi,bi->b", tails - want[elem], axis[elem])
    nb = rig.n_branch                                    # the axis points along the element's bones
    mean_along = np.bincount(elem[:nb], along[:nb], minlength=E) / np.maximum(np.bincount(elem[:nb], minlength=E), 1)
    assert (mean_along > 0).all()
    assert np.all(extent >= 8.0 - 1e-6) and np.all(extent <= 2048.0 + 1e-6)
    reach = np.zeros(E)
    np.maximum.at(reach, elem[:nb], np.linalg.norm(tails[:nb] - want[elem[:nb]], axis=1))
    assert np.abs(extent - np.clip(reach, 8.0, 2048.0)).max() <= 8.0 + 1e-6
    # every vertex's UV 1 points at its bone's element
    for mesh in (asset.branches, asset.leaves):
        if mesh is not None:
            assert np.array_equal(element_at_uv(pp.uv(mesh.bone), doc["width"], doc["height"]), elem[mesh.bone])
    return pp, doc


@pytest.mark.parametrize("variant", ("broad", "conifer_storm", "palm"))
def test_budget_rigs_read_back_as_epic_describes(variant, tmp_path):
    tree = _truth_tree(variant)
    pp, doc = _check(tree, tree_asset(tree, bone_budget=64), tmp_path)
    assert doc["levels"] <= 4 and doc["units"] == "cm"


def test_a_full_leafy_rig(tmp_path):
    tree, = api.generate("broad", node_budget=150, n_frames=24, seed=51)
    pp, doc = _check(tree, tree_asset(tree), tmp_path)
    assert doc["levels"] == 4 and len(pp.parent) > 20


def test_int_as_float_hand_case():
    # index 5 → bits 1029 = 0x0405: exponent 1, mantissa 5 → 2⁻¹⁴ · (1 + 5/1024)
    h = ppm.int_as_float(np.array([0, 5, 30000]))
    assert h.view(np.uint16).tolist() == [1024, 1029, 31024]
    assert float(h[1]) == pytest.approx(2.0 ** -14 * (1 + 5 / 1024))
    with pytest.raises(ValueError):
        ppm.int_as_float(np.array([30720]))


def test_wind_fit_recovers_a_known_swing_per_level():
    # a binary tree of 15 bones; every bone of an element at level l swings about X by A_l sin(2π f_l t
    # + φ_e): 2° at 0.5 Hz (trunk), 6° at 1.25 Hz, 9° at 2 Hz, phases per element 0 or 1 rad
    from tree_from_video.core.rotations import quat_to_matrix
    fps, F = 30.0, 240
    t = np.arange(F) / fps
    parent = np.array([-1] + [(k - 1) // 2 for k in range(1, 15)], np.int32)
    head = np.zeros((15, 3), np.float32)
    tail = np.zeros((15, 3), np.float32)
    for k in range(15):
        d = np.array([0.3 * ((k % 3) - 1), 0.2 * ((k % 2) - 0.5), 1.0], np.float32)
        head[k] = tail[parent[k]] if parent[k] >= 0 else 0.0
        tail[k] = head[k] + d
    rest = quat_to_matrix(bones.roll_zero_quats(head, tail))
    keys0 = BoneKeys(np.tile([1.0, 0, 0, 0], (F, 15, 1)), np.arange(1, F + 1, dtype=np.float32), None, np.zeros(15, bool))
    rig = Rig([f"B{k}" for k in range(15)], parent, head, tail, parent >= 0, np.zeros(15, np.int8), rest, keys0, None, fps)
    elem, eparent, level = ppm.branch_elements(rig)
    assert level.max() == 3 and (eparent[level == 0] == np.flatnonzero(level == 0)).all()
    amp = np.radians([2.0, 6.0, 9.0, 4.0])[level[elem]]
    hz = np.array([0.5, 1.25, 2.0, 3.0])[level[elem]]
    phase = (elem % 2).astype(float)
    angle = amp * np.sin(2 * np.pi * hz * t[:, None] + phase)
    rig.keys = BoneKeys(quat_exp(np.stack([angle, 0 * angle, 0 * angle], axis=-1)), keys0.frames, None, keys0.sampled)
    wind = {w["level"]: w for w in ppm.wind_levels(rig, elem, level, fps)}
    for lv, (a, f) in enumerate(((2.0, 0.5), (6.0, 1.25), (9.0, 2.0), (4.0, 3.0))):
        assert wind[lv]["frequency_hz"] == pytest.approx(f, abs=fps / F), lv
        assert wind[lv]["amplitude_deg"] == pytest.approx(a, rel=0.05), lv
    assert wind[0]["phase_spread_rad"] == 0.0
    mixed = [lv for lv in (1, 2, 3) if len(set(phase[np.isin(elem, np.flatnonzero(level == lv))])) > 1]
    assert mixed and all(wind[lv]["phase_spread_rad"] > 0.3 for lv in mixed)
