"""batch.py to the 3D tree: tree3d.npz, result.npz with nodes3d, FBX/USD/glTF/.blend/preview."""
import os
import subprocess
import sys

import numpy as np
import pytest
from job_report import check_report

from tree_from_video.core.tree3d import load_tree

from samples import ROOT, committed

pytestmark = [pytest.mark.bpy53]

BATCH = os.path.join(ROOT, "batch.py")
VIDEO = os.path.join(committed("broad"), "video.mp4")
OUTLINE = os.path.join(committed("broad"), "outline.json")


def _run(*args):
    p = subprocess.run([sys.executable, BATCH, *map(str, args)], capture_output=True, text=True, timeout=900)
    return p.returncode, p.stderr


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    d = tmp_path_factory.mktemp("batch3d") / "out"
    code, err = _run(VIDEO, "--outline", OUTLINE, "--out", d, "--npz", "--fbx", "--usd", "--gltf", "--blend",
                     "--preview", "--frames", "0:48", "--no-video", "--height", "12")
    assert code == 0, err
    return d


def test_every_requested_file_and_nothing_else(out):
    # the USD's leaf texture beside it (textures/), so the .usdc opens elsewhere
    assert sorted(os.listdir(out)) == sorted(["job.log", "overlay.png", "preview.png", "report.json", "result.npz",
                                              "skeleton.npz", "textures", "tree.blend", "tree.fbx", "tree.glb",
                                              "tree.usdc", "tree3d.npz"])
    doc = check_report(out)                      # the report lists every file with its size, and the rig
    assert {o["path"]: o["bytes"] for o in doc["outputs"]} == {
        os.path.relpath(os.path.join(r, f), out).replace(os.sep, "/"): os.path.getsize(os.path.join(r, f))
        for r, _, fs in os.walk(out) for f in fs if f not in ("report.json", "job.log")}
    assert doc["counts"]["bones"] > 100 and doc["counts"]["triangles"] > 10_000
    assert [f for f in os.listdir(out / "textures") if f.endswith(".png") and " " not in f]
    for name in os.listdir(out):
        if name in ("textures", "job.log"):
            continue
        assert os.path.getsize(out / name) > 1000, name
        assert oct(os.stat(out / name).st_mode & 0o044) == oct(0o044), f"{name} is not readable by others"


def test_result_has_nodes3d_with_fixed_branch_lengths(out):
    with np.load(out / "result.npz", allow_pickle=False) as z:
        n3, parents, n2 = z["nodes3d"], z["parents"], z["nodes2d"]
    assert n3.shape == (48, len(parents), 3) and n2.shape[:2] == n3.shape[:2]
    c = np.flatnonzero(parents >= 0)
    L = np.linalg.norm(n3[:, c] - n3[:, parents[c]], axis=-1)
    assert np.abs(L / L[:1] - 1).max() < 0.01
    assert n3[0, :, 2].max() == pytest.approx(12.0, rel=0.1)          # --height 12 (metres)
    assert np.allclose(n3[:, 0], 0.0)                                 # the base stays at the origin


def test_tree3d_file_loads(out):
    tree = load_tree(out / "tree3d.npz")
    assert tree.nodes3d.shape[0] == 48 and tree.fps == pytest.approx(24.0)
    assert tree.radius[0] > tree.radius.min() > 0                     # pipe model: trunk thickest


def test_preview_shows_the_tree_in_both_views(out):
    import cv2
    img = cv2.imread(str(out / "preview.png"))
    h, w = img.shape[:2]
    for half in (img[:, : w // 2], img[:, w // 2:]):
        bark = (np.abs(half.astype(int) - half[5, -5].astype(int)).sum(-1) > 60).mean()
        assert 0.01 < bark < 0.5, bark


def test_blend_file_is_a_blender_file(out):
    head = (out / "tree.blend").read_bytes()[:7]
    assert head == b"BLENDER" or head[:4] == b"\x28\xb5\x2f\xfd"      # plain or zstd-compressed
