"""Levels of detail (core/asset/lod.py, issue 33): LOD0..LOD3 of generated trees of three species
and a frond crown (seeds never tuned on) and of the synthetic samples' true trees: each level's
triangles near its share of LOD0's (40 %, 15 %, 6 %), its front silhouette at the size an engine
shows it (LOD k at 1/2ᵏ of LOD0's pixels) close to LOD0's (IoU) with the same cover, every vertex
on a bone of the one rig, lower levels without a flap; with a bone budget every level's bones are
the cut rig's."""
import dataclasses

import cv2
import numpy as np
import pytest
from test_loop import _truth_tree

from tree_from_video import api
from tree_from_video.core.asset import lod, tree_asset
from tree_from_video.core.detail.leaf_clusters import as_fronds

#: each level's triangle share of LOD0 may stray this far from lod.lod_shares (relative)
SHARE_TOL = 0.2
#: LOD k's front coverage at 256 / 2ᵏ pixels against LOD0's at the same size, soft IoU (measured on
#: the three species 0.81–0.83, 0.74–0.76, 0.73–0.75)
IOU_MIN = 0.72
#: a frond crown's levels, measured 0.75 / 0.63 / 0.56 (cover 0.94 / 0.72 / 0.57): a kept leaflet pair
#: grows about its stem, not along the midrib its dropped neighbours covered
FROND_IOU = (1.0, 0.72, 0.6, 0.52)
#: its covered pixels against LOD0's (measured 0.87–1.14)
COVER = (0.8, 1.25)
#: bare trees (no leaves to take the cut) per level, measured: LOD1 0.93–0.95 and then what is left
#: when hundreds of thin tubes share 15 % (6 %) of LOD0's triangles: capless 3-sided tubes (6
#: triangles) for every tube would already be 21 %, so the thinnest go (LOD2 0.58–0.77, LOD3
#: 0.32–0.59 on the four samples). Merging chains into one tube is what would raise these.
BARE_IOU = (1.0, 0.9, 0.55, 0.3)


def silhouette(level: lod.Lod, lo: np.ndarray, span: float, px: int, ss: int = 4) -> np.ndarray:
    """``(px, px)`` coverage in [0, 1] of ``level``'s polygons in the front view (X right, Z up),
    rasterised at ``ss``× and averaged down (as an engine's multisampling shows a thin twig)."""
    px, out = px * ss, px
    polys = []
    if level.branches is not None:                     # every polygon as a fan of triangles
        b = level.branches
        n = b.loop_total - 2
        face = np.repeat(np.arange(len(n)), n)
        k = np.arange(len(face)) - np.repeat(np.cumsum(n) - n, n)
        s = b.loop_start[face]
        tri = np.stack([b.loop_vert[s], b.loop_vert[s + k + 1], b.loop_vert[s + k + 2]], axis=1)
        polys.append(b.co[tri][..., [0, 2]])
    if level.leaves is not None:
        polys.append(level.leaves.co[:, [0, 2]].reshape(-1, 4, 2))
    P = (np.concatenate([q.reshape(-1, 2) for q in polys]) - lo) / span * (px - 1)
    P[..., 1] = px - 1 - P[..., 1]
    img = np.zeros((px, px), np.uint8)
    P = np.round(P * 16).astype(np.int32)
    sizes = [q.shape[1] for q in polys for _ in range(len(q))]
    split = np.split(P, np.cumsum(sizes)[:-1])
    for poly in split:                                   # one at a time: fillPoly's even-odd rule cancels overlaps
        cv2.fillConvexPoly(img, poly, 1, shift=4)
    return img.reshape(out, ss, out, ss).mean(axis=(1, 3))


def synth_tree_scale(tree) -> float:
    """The true trees' nodes are in metres (×0.03 of the sample's pixels), their radii still in
    pixels: the same factor."""
    return 0.03


def _trees():
    out = []
    for sp, seed in (("broad", 21), ("sparse", 22), ("conifer", 23)):
        t, = api.generate(sp, node_budget=150, n_frames=12, seed=seed)
        out.append((sp, t))
    t = out[0][1]
    out.append(("frond", dataclasses.replace(t, leaves=as_fronds(t, t.leaves))))
    return out


@pytest.fixture(scope="module")
def trees():
    return _trees()


def _check_levels(name, asset, iou_min=None):
    levels = asset.lods
    T0 = levels[0].triangles
    first = levels[0]
    pts = np.concatenate([first.branches.co] + ([first.leaves.co] if first.leaves is not None else []))[:, [0, 2]]
    lo = pts.min(0)
    span = float((pts.max(0) - lo).max())
    n_bones = len(asset.rig.names)
    for k, (level, share) in enumerate(zip(levels, lod.lod_shares(len(levels)))):
        got = level.triangles / T0
        assert abs(got - share) <= SHARE_TOL * share, f"{name} LOD{k}: {got:.3f} of LOD0's triangles, asked {share}"
        px = 256 >> k
        m0, m = silhouette(first, lo, span, px), silhouette(level, lo, span, px)
        iou = np.minimum(m, m0).sum() / np.maximum(m, m0).sum()          # soft IoU of the coverages
        cover = m.sum() / m0.sum()
        bar = IOU_MIN if iou_min is None else iou_min[k]
        assert iou >= bar, f"{name} LOD{k}: silhouette IoU {iou:.3f} at {px} px"
        if iou_min is None:
            assert COVER[0] <= cover <= COVER[1], f"{name} LOD{k}: cover {cover:.2f} of LOD0's"
        for mesh in (level.branches, level.leaves):
            if mesh is not None:
                assert mesh.bone.min() >= 0 and mesh.bone.max() < n_bones
        if k and level.leaves is not None:
            assert level.leaves.flap is None
        if level.branches is not None:              # every polygon's corners are real vertices
            assert level.branches.loop_vert.max() < len(level.branches.co)
            assert level.branches.loop_start[-1] + level.branches.loop_total[-1] == len(level.branches.loop_vert)


def test_levels_of_generated_trees_keep_their_share_and_silhouette(trees):
    for name, tree in trees:
        asset = tree_asset(tree, lods=4)
        assert len(asset.lods) == 4 and asset.lods[0].leaves is asset.leaves
        _check_levels(name, asset, FROND_IOU if name == "frond" else None)


@pytest.mark.parametrize("variant", ("broad", "conifer", "palm", "tiny"))
def test_levels_of_bare_true_trees(variant):
    tree = _truth_tree(variant)
    tree = dataclasses.replace(tree, radius=tree.radius * synth_tree_scale(tree))
    _check_levels(variant, tree_asset(tree, lods=4), BARE_IOU)


def test_a_budget_moves_every_level_onto_the_kept_bones(trees):
    name, tree = trees[0]
    full = tree_asset(tree, lods=3)
    cut = tree_asset(tree, lods=3, bone_budget=24)
    bone_of = cut.budget.bone_of
    assert len(cut.rig.names) <= 24 and bone_of.shape == (len(full.rig.names),)
    for a, b in zip(full.lods[1:], cut.lods[1:]):
        assert np.array_equal(bone_of[a.branches.bone], b.branches.bone)
        assert np.array_equal(bone_of[a.leaves.bone], b.leaves.bone)
        assert np.array_equal(a.leaves.co, b.leaves.co)
    assert cut.lods[0].branches is cut.branches


def test_tube_settings_hand_case():
    # 2(K − 1)S + 2(S − 2): 8 sides 6 rings = 92; the ladder 8×6, 7×5 (2·4·7 + 10 = 66), 6×4 (44),
    # 5×4 (36), 4×3 (20), 3×2 (8): under 40 the richest is 5×4, the next up 6×4
    assert lod.tube_triangles(8, 6) == 92
    assert lod.tube_ladder(8, 6) == [(8, 6), (7, 5), (6, 4), (5, 4), (4, 3), (3, 2)]
    assert lod.tube_settings(8, 6, 40) == ((5, 4), (6, 4))
    assert lod.tube_settings(8, 6, 100) == ((8, 6), (8, 6))
    assert lod.tube_settings(8, 6, 1) == ((3, 2), (3, 2))
    assert list(lod.kept_cards(16, 4, False)) == [0, 5, 10, 15]
    assert list(lod.kept_cards(16, 4, True)) == [0, 1, 14, 15]
    assert lod.lod_shares(5) == pytest.approx((1.0, 0.4, 0.15, 0.06, 0.024))
