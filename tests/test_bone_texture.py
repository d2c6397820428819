"""The bone-animation texture (core/asset/bone_texture.py, issue 33): a reference decoder written
from the sidecar's description rebuilds every frame's vertex positions from ``bone_anim.exr`` +
``bone_anim.json`` (read with a reader written from the OpenEXR layout, tests/exr_reader.py) within
0.1 % of the tree's height of where the rig puts them, composed the way Blender composes pose bones
(test_budget._pose_world), for bone budgets of held-out samples, a loop, and a full rig; the EXR
writer's halfs come back bit for bit; the encoding is checked on a hand case."""
import dataclasses
import json

import numpy as np
import pytest
from exr_reader import read_exr, rgba
from test_budget import _pose_world
from test_loop import _truth_tree

from tree_from_video import api
from tree_from_video.core.asset import bone_texture as bt
from tree_from_video.core.asset import tree_asset
from tree_from_video.core.asset.exr import write_exr
from tree_from_video.core.loop import loop_tree

TOL = 0.001          # of the tree's height, every vertex, every frame


def decode(doc: dict, px: np.ndarray, p: np.ndarray, bone: np.ndarray, frame: int) -> np.ndarray:
    """Positions ``(V, 3)`` (glTF axes) at ``frame`` of bind positions ``p (V, 3)`` (glTF axes) of
    bones ``bone (V,)``, from the sidecar's words: texel 2k = head displacement t, texel 2k+1 =
    quaternion (x, y, z, w); x = h_k + t + q (p − h_k)."""
    assert doc["axes"].startswith("glTF") and doc["units"] == "m"
    row = px[frame]
    t = row[2 * bone, :3].astype(np.float64)
    q = row[2 * bone + 1].astype(np.float64)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    h = np.asarray(doc["bind_heads"], np.float64)[bone]
    v, w = q[:, :3], q[:, 3:]
    r = p - h
    rotated = r + 2 * w * np.cross(v, r) + 2 * np.cross(v, np.cross(v, r))     # q r q*
    return h + t + rotated


def _vertices(asset):
    co = np.concatenate([asset.branches.co] + ([asset.leaves.co] if asset.leaves is not None else []))
    bone = np.concatenate([asset.branches.bone] + ([asset.leaves.bone] if asset.leaves is not None else []))
    return co.astype(np.float64), bone


def _check(tree, asset, tmp_path, label):
    tex = bt.bone_texture(tree, asset.rig)
    exr, js = bt.write_bone_texture(tmp_path, tex)
    doc = json.load(open(js))
    px = rgba(exr)
    F = doc["frame_count"]
    assert px.shape == (F, 2 * len(asset.rig.names), 4) and doc["bones"] == asset.rig.names
    co, bone = _vertices(asset)
    W = _pose_world(asset.rig)                                      # Blender's composition, Blender axes
    A = bt.TO_GLTF
    H = float(np.ptp(tree.nodes3d[0][:, 2]))
    worst = 0.0
    for f in range(F):
        want = np.einsum("vij,vj->vi", W[f, bone, :3, :3], co) + W[f, bone, :3, 3]
        got = decode(doc, px, co @ A.T, bone, f)
        worst = max(worst, float(np.abs(got - want @ A.T).max()) / H)
    assert worst <= TOL, f"{label}: decoded vertices off by {100 * worst:.3f} % of the height"
    return doc, worst


@pytest.mark.parametrize("variant", ("broad", "conifer_storm", "palm"))
def test_budget_rigs_decode_within_a_thousandth(variant, tmp_path):
    tree = _truth_tree(variant)
    asset = tree_asset(tree, bone_budget=32)
    doc, _ = _check(tree, asset, tmp_path, variant)
    assert not doc["loop"] and doc["frame_count"] == tree.n_frames


def test_a_looped_leafy_budget_rig_and_a_full_rig(tmp_path):
    tree, = api.generate("broad", node_budget=120, n_frames=90, seed=41)
    looped, _ = loop_tree(tree, 2.0)
    asset = tree_asset(looped, bone_budget=64)
    doc, _ = _check(looped, asset, tmp_path, "loop")
    assert doc["loop"] and doc["frame_count"] == looped.n_frames - 1          # the closing frame not repeated
    bare = dataclasses.replace(tree, leaves=None)
    full = tree_asset(bare, every_key=True)
    assert full.rig.keys.location is None
    _check(bare, full, tmp_path, "full rig")


def test_encoding_hand_case():
    # one bone, head (1, 0, 0) in Blender axes, turned 90° about Blender's Z: a point (2, 0, 0)
    # goes to (1, 1, 0); in glTF axes head (1, 0, 0), the point (2, 0, 0) → (1, 0, −1)
    q = np.array([np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)])
    h = np.array([1.0, 0.0, 0.0])
    A = bt.TO_GLTF
    v = A @ q[1:]
    px = np.zeros((1, 2, 4), np.float32)
    px[0, 1] = [*v, q[0]]
    doc = {"axes": "glTF", "units": "m", "bind_heads": [list(A @ h)]}
    got = decode(doc, px, np.array([A @ [2.0, 0.0, 0.0]]), np.array([0]), 0)
    assert np.allclose(got, [[1.0, 0.0, -1.0]], atol=1e-3)


def test_exr_halfs_round_trip(tmp_path):
    rng = np.random.default_rng(5)
    img = rng.normal(size=(7, 13, 4)).astype(np.float16)
    write_exr(tmp_path / "x.exr", img)
    header, _ = read_exr(tmp_path / "x.exr")
    assert header["_channels"] == ["A", "B", "G", "R"]
    assert np.array_equal(rgba(tmp_path / "x.exr"), img.astype(np.float32))
