"""Billboards (issue 36 part 2, ``--billboard PX``): the tree's front rendered in Blender, read back
through what billboard.json says (its scale and where the tree's origin lands), against the tree's
own mesh rasterized here: the alpha is the silhouette (IoU ≥ 0.98 on the branch tubes where the mesh
covers a pixel clearly; inside the leaf cards' silhouette with leaves, whose cut-out leaves cover
less), the normals face the viewer, the generate batch writes one per tree, and the picture is an
exemplar for --variations."""
import json
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from tree_from_video.core.asset import tree_asset
from tree_from_video.core.generate.exemplars import read_exemplar
from tree_from_video.core.tree3d import load_tree

from samples import ROOT

BATCH = os.path.join(ROOT, "batch.py")
pytestmark = pytest.mark.slow


def run(*args):
    p = subprocess.run([sys.executable, BATCH, *map(str, args)], capture_output=True, text=True, timeout=600)
    return p.returncode, p.stdout, p.stderr


def mesh_silhouette(folder: str, doc: dict, leaves: bool) -> np.ndarray:
    """``(H, W)`` float 0..1: the share of each pixel the tree's rest mesh (branch polygons, and leaf quads with ``leaves``)
    projected as billboard.json says: x = origin_x + X / m, y = origin_y − Z / m (Blender axes)."""
    tree = load_tree(os.path.join(folder, "tree3d.npz"))
    asset = tree_asset(tree, leaves=leaves)
    m = doc["metres_per_px"]
    ox, oy = doc["origin_px"]
    w, h = doc["size_px"]
    k = 4                                       # coverage: rasterized 4 × 4 per pixel, then averaged
    img = np.zeros((h * k, w * k), np.uint8)

    def px(co):
        # a pixel's centre at +½: in the fine grid, pixel (i, j) of the fine image covers [i, i + 1)
        return (np.stack([ox + co[:, 0] / m, oy - co[:, 2] / m], 1) * k - 0.5) * 16

    b = asset.branches
    xy = px(b.co)
    polys = [np.round(xy[b.loop_vert[s:s + n]]).astype(np.int32) for s, n in zip(b.loop_start, b.loop_total)]
    if leaves and asset.leaves is not None:
        polys += list(np.round(px(asset.leaves.co)).astype(np.int32).reshape(-1, 4, 2))
    for poly in polys:          # one at a time: fillPoly of many fills their even-odd union (a tube's
        cv2.fillConvexPoly(img, poly, 1, cv2.LINE_8, 4)      # front and back faces would cancel)
    return img.reshape(h, k, w, k).mean(axis=(1, 3))


def test_billboard_alpha_is_the_silhouette(tmp_path):
    out = tmp_path / "bare"
    code, _, err = run("--generate", 1, "--species", "sparse", "--no-leaves", "--seed", 7, "--seconds", 1,
                       "--billboard", 512, "--out", out, "--quiet")
    assert code == 0, err
    folder = out / "tree_000"
    doc = json.loads((folder / "billboard.json").read_text())
    rgba = cv2.imread(str(folder / "billboard.png"), cv2.IMREAD_UNCHANGED)
    nrm = cv2.imread(str(folder / "billboard_normal.png"), cv2.IMREAD_UNCHANGED)
    assert rgba.shape[:2] == (doc["size_px"][1], doc["size_px"][0]) and max(rgba.shape[:2]) == 512
    assert rgba.shape[2] == 4 and nrm.shape == rgba.shape
    a = rgba[..., 3] / 255.0
    cov = mesh_silhouette(str(folder), doc, leaves=False)
    alpha, sil = a >= 0.5, cov >= 0.5
    # where a face covers a pixel only in part (twigs under a pixel wide, edges) Blender's filtered
    # anti-aliasing and this box coverage may fall either side of ½: IoU over the pixels the mesh
    # covers clearly (≤ 0.2 or ≥ 0.8); a framing one pixel off drops it to ~0.84
    sure = (cov <= 0.2) | (cov >= 0.8)
    iou = (alpha & sil & sure).sum() / ((alpha | sil) & sure).sum()
    plain = (alpha & sil).sum() / (alpha | sil).sum()
    corr = np.corrcoef(a.ravel(), cov.ravel())[0, 1]
    print(f"bare tree: alpha vs the mesh's silhouette IoU {iou:.4f} where clear ({plain:.4f} over every pixel), "
          f"coverage correlation {corr:.4f}")
    assert iou >= 0.98 and plain >= 0.9 and corr >= 0.98
    # the normals face the viewer (glTF +Z), the trunk's most of all
    n = nrm[..., [2, 1, 0]].astype(np.float64) / 255.0 * 2.0 - 1.0
    facing = (n[alpha][:, 2] > 0).mean()
    print(f"normals facing the viewer: {facing:.3f}")
    assert facing >= 0.95 and np.allclose(np.linalg.norm(n[alpha], axis=1), 1.0, atol=0.02)
    assert (nrm[..., 3] == rgba[..., 3]).all()


def test_generate_writes_a_billboard_per_tree_usable_as_exemplar(tmp_path):
    out = tmp_path / "leafy"
    code, _, err = run("--generate", 2, "--species", "broad", "--seed", 11, "--seconds", 1, "--billboard", 256,
                       "--out", out, "--quiet")
    assert code == 0, err
    index = json.loads((out / "generated.json").read_text())
    for entry in index["trees"]:
        assert f"{entry['folder']}/billboard.png" in entry["files"]
        folder = out / entry["folder"]
        doc = json.loads((folder / "billboard.json").read_text())
        alpha = cv2.imread(str(folder / "billboard.png"), cv2.IMREAD_UNCHANGED)[..., 3] >= 128
        sil = mesh_silhouette(str(folder), doc, leaves=True) >= 0.5
        inside = (alpha & sil).sum() / alpha.sum()
        cover = alpha.sum() / sil.sum()
        print(f"{entry['folder']}: alpha inside the mesh's silhouette {inside:.4f}, covers {cover:.2f} of it")
        assert inside >= 0.98 and cover >= 0.4
        e = read_exemplar(folder / "billboard.png")                 # a billboard is an exemplar
        assert e.has_trunk
    code, _, err = run("--variations", 2, "--exemplars", out / "tree_000" / "billboard.png",
                       out / "tree_001" / "billboard.png", "--out", tmp_path / "var", "--quiet")
    assert code == 0, err


def test_billboard_size_is_checked(tmp_path):
    code, _, err = run("--generate", 1, "--species", "broad", "--billboard", 4, "--out", tmp_path / "x")
    assert code == 2 and "--billboard 4" in err and len(err.strip().splitlines()) == 1
