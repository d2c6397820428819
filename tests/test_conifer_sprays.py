"""A conifer's foliage is needle sprays (core/detail/leaf_clusters.py ``spray_template``,
core/detail/leaf_texture.py ``spray_pixels``): the cards' layout and the texture by hand, the shape
a conifer's tree gets, reconstructed or grown, and the texture Blender's leaf material packs."""
import numpy as np
import pytest

from tree_from_video.core.detail import leaf_texture as lt
from tree_from_video.core.detail.leaf_clusters import ROLL_DEG, as_sprays, leaf_mesh, spray_template
from tree_from_video.core.tree3d import LeafClusters, Tree3D, load_tree, save_tree


def test_spray_cards_fan_level_droop_and_stay_in_the_cluster():
    r, size = 0.5, 0.55 * 0.5
    co, uv = spray_template(64, r, size, seed=3)
    q = co.reshape(64, 4, 3)
    stem, tip = 0.5 * (q[:, 0] + q[:, 1]), 0.5 * (q[:, 2] + q[:, 3])
    along = tip - stem
    length = np.linalg.norm(along, axis=1)
    assert np.all((length >= 1.6 * size * 0.7 - 1e-9) & (length <= 1.6 * size + 1e-9))
    d = along / length[:, None]
    droop = np.degrees(np.arcsin(-d[:, 2]))
    assert droop.min() >= 5 - 1e-6 and droop.max() <= 25 + 1e-6                # every spray droops to its tip
    fan = np.degrees(np.arctan2(np.abs(d[:, 0]), d[:, 1]))
    assert fan.max() <= 35 + 1e-6                                               # away from the trunk (+Y), fanned
    width = q[:, 1] - q[:, 0]
    np.testing.assert_allclose(np.linalg.norm(width, axis=1), 0.44 * length, rtol=1e-9)
    np.testing.assert_allclose(np.einsum("ij,ij->i", width, along), 0.0, atol=1e-12)   # across the twig
    # the tilt about the twig: the width's angle out of the level plane, at most ROLL_DEG
    level = np.cross(d, [0.0, 0.0, 1.0])
    level /= np.linalg.norm(level, axis=1, keepdims=True)
    tilt = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", width / np.linalg.norm(width, axis=1)[:, None],
                                                          level)), 0, 1)))
    assert tilt.max() <= ROLL_DEG + 1e-6 and tilt.max() > 0.5 * ROLL_DEG        # tilted, not all level
    assert np.linalg.norm(co, axis=1).max() <= 1.05 * r                         # within the cluster
    middle = 0.5 * (stem + tip)
    assert np.abs(middle).max(0)[0] <= 0.45 * r + 1e-9
    tilts = np.abs(np.degrees(np.arcsin(np.clip(width[:, 2] / np.linalg.norm(width, axis=1), -1, 1))))
    assert tilts[0] >= np.median(tilts)                                        # most tilted first (LODs keep it)
    np.testing.assert_array_equal(uv[:4], [[0, 0], [1, 0], [1, 1], [0, 1]])


def test_needle_spray_texture_by_hand():
    """The twig up the middle, needles every NEEDLE_STEP leaving it at NEEDLE_ANGLE_DEG toward the
    tip (a needle seen at x from the twig has left it x·cot θ lower), nothing beyond their reach."""
    n = 512
    a = lt.spray_pixels(n)[..., 3]
    v = np.arange(n) / (n - 1)
    mid = a[:, n // 2]
    assert mid[(v > 0.05) & (v < 0.95)].min() == pytest.approx(1.0)             # the twig
    assert a[:, int((0.5 + lt.NEEDLE_REACH) * (n - 1)) + 3:].max() == 0.0       # beyond the needles' reach
    col = lambda x: a[:, int(round((0.5 + x) * (n - 1)))]                       # noqa: E731
    on = col(0.2) > 0.5
    starts = np.flatnonzero(on[1:] & ~on[:-1])
    sel = starts[(v[starts] > 0.35) & (v[starts] < 0.65)]
    step = np.diff(v[sel]).mean()
    assert step == pytest.approx(lt.NEEDLE_STEP, rel=0.05)                      # one needle every step
    # follow one needle outward: its row rises by Δx · cot θ
    v1 = v[np.flatnonzero(col(0.1) > 0.5)]
    v2 = v[np.flatnonzero(col(0.3) > 0.5)]
    k = v1[(v1 > 0.4) & (v1 < 0.45)][0]
    rise = 0.2 / np.tan(np.radians(lt.NEEDLE_ANGLE_DEG))
    assert np.abs(v2 - (k + rise)).min() <= 2.0 / n
    assert 0.3 <= a.mean() <= 0.6                                               # needles with gaps between
    grey = lt.spray_pixels(64, (0.2, 0.4, 0.1))
    assert grey[..., 1].max() <= 0.4 + 1e-6 and grey[..., 0].max() <= 0.2 + 1e-6   # the tint
    np.testing.assert_array_equal(lt.shape_pixels("spray", 64), lt.spray_pixels(64))
    np.testing.assert_array_equal(lt.shape_pixels("frond", 64), lt.leaf_pixels(64))


def _conifer(tmp_path):
    parents = np.array([-1, 0, 1, 1])
    nodes = np.array([[[0, 0, 0], [0, 0, 4], [0, 0, 8], [2, 1, 5]]], np.float32).repeat(2, 0)
    tree = Tree3D(parents, nodes, np.ones(4, np.float32), np.zeros(4, np.int32), 24.0, "cedar", {"form": "conifer"})
    pos = np.array([[2.0, 1.0, 5.0], [-1.0, -2.0, 3.0], [0.0, 0.0, 7.5]], np.float32)
    lv = LeafClusters(np.array([3, 1, 2]), pos, np.tile(np.float32([0, 0, 1]), (3, 1)),
                      np.tile(np.float32([0.2, 0.4, 0.2]), (3, 1)), np.zeros(3, bool), np.zeros((2, 3), np.float32),
                      0.6, 0.33, 12)
    return tree, lv


def test_sprays_point_away_from_the_trunk_and_survive_the_file(tmp_path):
    tree, lv = _conifer(tmp_path)
    tree.leaves = as_sprays(tree, lv)
    assert tree.leaves.shape == "spray"
    ax = tree.leaves.axis.astype(float)
    np.testing.assert_allclose(ax[:, 2], 0.0, atol=1e-7)                        # level
    np.testing.assert_allclose(ax[0], np.array([2, 1, 0]) / np.sqrt(5), atol=1e-6)
    np.testing.assert_allclose(ax[1], np.array([-1, -2, 0]) / np.sqrt(5), atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(ax[2]), 1.0, atol=1e-6)           # on the trunk's line: its bone's
    m = leaf_mesh(tree.leaves)
    assert m["quads"] == 3 * 12 and np.isfinite(m["co"]).all()
    save_tree(tmp_path / "cedar.npz", tree)
    assert load_tree(tmp_path / "cedar.npz").leaves.shape == "spray"
    assert as_sprays(tree, None) is None


def test_grown_conifers_wear_sprays_and_broadleaves_clusters():
    from tree_from_video import api
    conifer = api.generate("conifer", 1, seed=4, node_budget=150)[0]
    broad = api.generate("broad", 1, seed=4, node_budget=150)[0]
    assert conifer.meta["form"] == "conifer" and conifer.leaves is not None and conifer.leaves.shape == "spray"
    assert broad.leaves is not None and broad.leaves.shape == "cluster"


@pytest.mark.blender
def test_the_leaf_material_packs_the_needle_spray():
    import bpy

    from tree_from_video.operators.scene import materials as mats
    img = mats.leaf_image("Spray", None, (1.0, 1.0, 1.0), "spray")
    try:
        px = np.array(img.pixels[:], np.float32).reshape(img.size[1], img.size[0], 4)
        np.testing.assert_allclose(px[..., 3], lt.spray_pixels(lt.TEXTURE_SIZE)[..., 3], atol=1 / 255)
    finally:
        bpy.data.images.remove(img)
