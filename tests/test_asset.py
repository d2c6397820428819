"""The asset stage (core/asset/, issue 33): what every writer copies, computed without Blender and
checked against the tree it comes from — the rig's rotations pose the tree's nodes, the reduced
keys stay within the stated tolerance, every mesh vertex rides the bone it sits on, roles mark the
trunk, limbs and twigs, the look carries the defaults."""
import dataclasses

import numpy as np
import pytest

from tree_from_video import api
from tree_from_video.core import bones, keys
from tree_from_video.core.asset import roles, tree_asset
from tree_from_video.core.detail.branch_mesh import MeshParams
from tree_from_video.core.topology import trunk_chain


@pytest.fixture(scope="module")
def grown():
    """A generated tree with twigs and leaves (40 nodes, 24 frames)."""
    tree, = api.generate("broad", node_budget=40, n_frames=24, seed=5, twig_depth=1)
    assert tree.leaves is not None and tree.leaves.count > 0
    return tree


def _height(tree) -> float:
    return float(np.ptp(tree.nodes3d[0][:, 2]))


def test_the_rigs_rotations_pose_the_trees_nodes(grown):
    asset = tree_asset(grown, every_key=True)
    rig = asset.rig
    B, S = grown.n_nodes - 1, grown.leaves.count
    assert len(rig.names) == B + S and rig.n_branch == B and rig.leaf_names[0] == "L0000"
    assert rig.keys.keep is None and rig.keys.local.shape == (grown.n_frames, B, 4)
    # parents come before children; heads and tails at the rest nodes; branch bones connected
    assert (rig.parent < np.arange(B + S)).all() and rig.connected[:B].sum() == B - 1 and not rig.connected[B:].any()
    edges = bones.bone_edges(grown.parents)
    np.testing.assert_allclose(rig.tail[:B], grown.nodes3d[0][edges[:, 1]], atol=1e-6)
    # forward kinematics of the rig's local rotations from its rest pose = the tree at every frame
    nodes, _ = bones.pose(grown.parents, grown.nodes3d[0], rig.rest, rig.keys.local)
    err = np.abs(nodes - grown.nodes3d.astype(np.float64)).max()
    assert err < 1e-5 * _height(grown), err
    # the leaf bones' flutter: every frame, a turn about the bone's Y only
    lk = rig.leaf_keys
    assert lk is not None and not lk.cyclic and lk.q.shape == (grown.n_frames, S, 4)
    assert np.allclose(lk.q[..., [1, 3]], 0.0) and np.allclose(np.linalg.norm(lk.q, axis=-1), 1.0)


def test_reduced_keys_stay_within_the_tolerance(grown):
    rig = tree_asset(grown).rig
    k = rig.keys
    assert k.keep is not None and k.left is not None and k.keep[[0, -1]].all()
    assert not k.sampled.any() or k.keep[:, k.sampled].all()          # a sampled bone keeps every frame
    played = keys.interpolate(k.local, k.keep, k.frames)
    nodes, _ = bones.pose(grown.parents, grown.nodes3d[0], rig.rest, played)
    err = np.linalg.norm(nodes - grown.nodes3d.astype(np.float64), axis=-1).max()
    assert err <= keys.KEY_TOLERANCE * _height(grown) * 1.001, (err, keys.KEY_TOLERANCE)
    assert rig.reduced is not None and k.keep.sum() < k.keep.size        # something was left out


def test_every_vertex_rides_the_bone_it_sits_on(grown):
    asset = tree_asset(grown)
    rig, branches, leaves = asset.rig, asset.branches, asset.leaves
    assert branches is not None and leaves is not None
    B = rig.n_branch
    # a tube's vertex lies within its bone's reach: at most its radius (plus curl and bark) off
    # the segment from head (extended inside the parent) to tail
    h, t = rig.head[branches.bone].astype(np.float64), rig.tail[branches.bone].astype(np.float64)
    d = t - h
    u = np.clip(np.sum((branches.co - h) * d, 1) / np.sum(d * d, 1), -0.6, 1.0)
    off = np.linalg.norm(branches.co - (h + u[:, None] * d), axis=1)
    assert off.max() < 0.05 * _height(grown), off.max()
    assert set(np.unique(branches.bone)) == set(range(B))
    # a leaf card's vertex is within its cluster's reach of the cluster's bone head
    lv = grown.leaves
    assert leaves.bone.min() >= B                                         # the rig's leaf bones follow its branches
    reach = np.linalg.norm(leaves.co - rig.head[leaves.bone], axis=1)
    assert reach.max() <= (lv.radius + lv.leaf_size) * float(lv.scales().max()) * 1.01 + 1e-6
    assert leaves.quads == lv.polygons and leaves.flap is not None
    assert leaves.flap.offsets.shape == (4, len(leaves.co), 3) and leaves.flap.weights.shape == (grown.n_frames, 4)


def test_roles_mark_trunk_limbs_twigs_and_leaf_clusters(grown):
    role = roles.node_roles(grown)
    first = roles.first_twig_node(grown)
    assert first < grown.n_nodes                                         # twig_depth=1 added twigs
    assert (role[first:] == roles.TWIG).all() and (role[:first] != roles.TWIG).all()
    assert set(np.flatnonzero(role == roles.TRUNK)) == set(trunk_chain(grown.parents).tolist())
    assert (role[:first][role[:first] != roles.TRUNK] == roles.LIMB).all()
    regrown = dataclasses.replace(grown, meta={**grown.meta, "limbs": "grown"})
    r2 = roles.node_roles(regrown)
    assert ((r2 == roles.GROWN_LIMB) == (role == roles.LIMB)).all()
    rig = tree_asset(grown, every_key=True).rig
    edges = bones.bone_edges(grown.parents)
    assert (rig.role[:rig.n_branch] == role[edges[:, 1]]).all()
    assert (rig.role[rig.n_branch:] == roles.LEAF_CLUSTER).all()
    counts = roles.role_counts(rig.role)
    assert counts["leaf cluster"] == grown.leaves.count and counts["twig"] == grown.n_nodes - first


def test_the_leaf_tint_keeps_the_foliages_hue_by_hand():
    """leaf_tint = the clusters' median × k, k the 90th percentile of each cluster's largest
    channel ratio to the median (capped at 1 in the brightest channel): 18 clusters at 0.6–1.5 ×
    (0.4, 0.5, 0.25) and two of sky (0.6, 0.7, 0.9)."""
    from types import SimpleNamespace

    from tree_from_video.core.asset.look import leaf_colour, leaf_tint
    base = np.array([0.4, 0.5, 0.25])
    colour = np.vstack([base * np.linspace(0.6, 1.5, 18)[:, None], [[0.6, 0.7, 0.9]] * 2])
    leaves = SimpleNamespace(colour=colour)
    median = leaf_colour(leaves)
    np.testing.assert_allclose(median / median.sum(), base / base.sum())     # the sky is not the median
    tint = leaf_tint(leaves)
    # 90th percentile of 20 ratios (linear): 0.1 of the way from the 18th to the 19th sorted; the
    # 18th is the brightest green (1.5 / its median scale), the 19th a sky
    ratio = np.sort((colour / median).max(axis=1))
    np.testing.assert_allclose(tint, median * (ratio[17] + 0.1 * (ratio[18] - ratio[17])))
    np.testing.assert_allclose(tint / tint.sum(), base / base.sum())          # the foliage's hue
    assert ((colour <= tint + 1e-12).all(axis=1)).mean() == 0.9
    # the per-channel 90th percentile it replaces: the sky's blue greys it (HSV saturation 0.5 -> 0.39)
    old = np.percentile(colour, 90, axis=0)
    sat = lambda c: 1 - c.min() / c.max()                                     # noqa: E731
    assert sat(tint) == pytest.approx(0.5) and sat(old) < 0.4
    # a bright crown: capped at 1 in its brightest channel, never below the median
    bright = SimpleNamespace(colour=np.vstack([[0.8, 0.9, 0.5]] * 5 + [[0.95, 1.0, 0.9]] * 6))
    assert leaf_tint(bright).max() == pytest.approx(1.0) and (leaf_tint(bright) >= leaf_colour(bright)).all()


def test_the_look_carries_the_recorded_settings_and_the_defaults(grown):
    look = tree_asset(grown).look
    assert (look.mesh.curliness, look.mesh.bark) == (MeshParams().curliness, MeshParams().bark)
    assert look.leaf_tint is not None and (look.leaf_tint >= look.leaf_colour - 1e-9).all()
    assert look.bark_colour is None and len(look.bark_solid) == 4
    brown = dataclasses.replace(grown, meta={**grown.meta, "bark_colour": {"colour": [0.3, 0.2, 0.1]}})
    look = tree_asset(brown, curliness=0.0, bark="none", mesh=False, leaves=False).look
    assert list(look.bark_colour) == [0.3, 0.2, 0.1] and (look.mesh.curliness, look.mesh.bark) == (0.0, "none")
