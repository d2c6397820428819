"""Collision capsules (core/asset/collision.py, issue 33): on generated trees of three species and
the samples' true trees (seeds never tuned on), the trunk's and main limbs' bones lie inside their
capsules, the trunk's base inside the first; at most 16 capsules, named ``UCP_<tree>_NN``; each
capsule's mesh is closed and its vertices lie on the capsule (Unreal fits a capsule to them)."""
import dataclasses
import json

import numpy as np
import pytest
from test_loop import _truth_tree

from tree_from_video import api
from tree_from_video.core import bones
from tree_from_video.core.asset import collision as col
from tree_from_video.core.asset import tree_asset
from tree_from_video.core.asset.pivot_painter import branch_elements, element_bases


def _dist_to_segment(p, a, b):
    d = b - a
    t = np.clip((p - a) @ d / max(float(d @ d), 1e-12), 0, 1)
    return np.linalg.norm(p - (a + t[..., None] * d), axis=-1)


def _check(tree, tmp_path):
    asset = tree_asset(tree, leaves=False, collision=True)
    caps, rig = asset.capsules, asset.rig
    assert 1 <= len(caps) <= col.MAX_CAPSULES
    edges = bones.bone_edges(tree.parents)
    radius = np.maximum(tree.radius[edges[:, 0]], tree.radius[edges[:, 1]]).astype(np.float64)
    elem, _, level = branch_elements(rig)
    base = element_bases(rig, elem, len(level))
    trunk_r = radius[base[level == 0]].max()
    # the trunk's base sits in a capsule
    root = rig.head[np.flatnonzero(rig.parent < 0)[0]].astype(np.float64)
    assert min(_dist_to_segment(root, c.a, c.b) - c.radius for c in caps) <= 1e-6
    # the thickest bones of the chosen branches are inside some capsule (ends within radius + bend)
    thick = np.flatnonzero((level[elem] <= 1) & (radius >= max(col.MIN_RADIUS_SHARE * trunk_r, caps[-1].radius)))
    for b in thick:
        for p in (rig.head[b], rig.tail[b]):
            inside = [_dist_to_segment(p.astype(np.float64), c.a, c.b) <= c.radius * (1 + col.MAX_BEND) + 1e-6
                      for c in caps]
            assert any(inside), f"bone {rig.names[b]} outside every capsule"
    for c in caps:
        co, lv, tot = col.capsule_mesh(c)
        d = _dist_to_segment(co, c.a, c.b)
        assert np.abs(d - c.radius).max() <= 0.02 * c.radius
        edges_ = {}
        start = 0
        for n in tot:                                                 # every edge used by two faces
            f = lv[start:start + n]
            for i in range(n):
                e = tuple(sorted((int(f[i]), int(f[(i + 1) % n]))))
                edges_[e] = edges_.get(e, 0) + 1
            start += n
        assert set(edges_.values()) == {2}
    path = col.write_collision(tmp_path, tree.name, caps)
    doc = json.load(open(path))
    assert [c["name"] for c in doc["capsules"]] == [col.capsule_name(tree.name, k) for k in range(len(caps))]
    assert all(n.startswith("UCP_") and " " not in n for n in (c["name"] for c in doc["capsules"]))
    return caps


@pytest.mark.parametrize("species,seed", [("broad", 71), ("sparse", 72), ("conifer", 73)])
def test_generated_trees(species, seed, tmp_path):
    tree, = api.generate(species, node_budget=150, n_frames=6, seed=seed)
    _check(tree, tmp_path)


@pytest.mark.parametrize("variant", ("broad", "palm"))
def test_true_trees(variant, tmp_path):
    tree = _truth_tree(variant)
    _check(dataclasses.replace(tree, radius=tree.radius * 0.03), tmp_path)
