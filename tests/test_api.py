"""The public scripting API (``from tree_from_video import api``), called as a pipeline TD's script
would: reconstruct a clip, build the 3D tree, save and load it, read its meta by key, grow new
trees, and in Blender build and export one."""
import os

import bpy
import numpy as np
import pytest
from test_exports import accessor, read_glb

from tree_from_video import api

from samples import committed

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

VIDEO = os.path.join(committed("broad"), "video.mp4")
OUTLINE = os.path.join(committed("broad"), "outline.json")


@pytest.fixture(scope="module")
def result():
    return api.reconstruct(VIDEO, OUTLINE, frames="0:24")


@pytest.fixture(scope="module")
def tree(result):
    return api.build_3d(result, twigs=1, leaf_density=0.3, height_m=12.0, name="API oak")


def test_reconstruct_gives_the_moving_2d_skeleton(result):
    sk = result.skeleton
    assert sk.nodes2d.shape == (24, sk.n_nodes, 2) and sk.n_nodes > 50
    assert result.start == 0 and result.stop == 24


def test_build_3d_takes_keywords_and_the_meta_reads_by_key(tree, result):
    assert tree.name == "API oak" and tree.nodes3d.shape[0] == 24
    assert tree.n_nodes > result.skeleton.n_nodes                      # twigs=1 added twig nodes
    assert tree.leaves is not None and tree.leaves.count > 10
    height = float(np.ptp(tree.nodes3d[0][:, 2]))
    assert 11.0 < height <= 12.0 + 1e-3                                 # height_m=12 (leaves aside)
    w, h = tree.meta["video_size"]
    assert (w, h) == (result.outline.mask.shape[1], result.outline.mask.shape[0])
    assert tree.meta["metres_per_px"] == pytest.approx(12.0 / tree.meta["height_px"], rel=1e-6)
    bx, by = tree.meta["base_px"]
    assert 0 <= bx < w and 0 <= by < h


def test_save_and_load_round_trip(tree, tmp_path):
    path = api.save_tree(tree, tmp_path / "t.npz")
    assert os.path.isabs(path) and os.path.isfile(path)
    back = api.load_tree(path)
    np.testing.assert_array_equal(back.parents, tree.parents)
    np.testing.assert_allclose(back.nodes3d, tree.nodes3d)
    assert back.meta["base_px"] == tree.meta["base_px"] and back.leaves.count == tree.leaves.count
    with pytest.raises(api.InputError, match="does not exist"):
        api.load_tree(tmp_path / "missing.npz")


def test_settings_are_the_products_and_bad_ones_are_refused():
    s = api.settings()
    assert (s.twigs.depth, s.curliness, s.bark, s.levels) == (2, 0.3, "rough", 6)
    assert api.settings(leaves=False).leaves is None
    assert api.settings(conifer=True, solver="deterministic").motion.solver == "deterministic"
    with pytest.raises(api.InputError, match="unknown setting 'twig_count'"):
        api.settings(twig_count=2)
    with pytest.raises(api.InputError, match="levels 12 out of range; use 2..9"):
        api.settings(levels=12)
    with pytest.raises(api.InputError, match="unknown bark 'bumpy'"):
        api.settings(bark="bumpy")


def test_generate_grows_distinct_seeded_trees():
    a = api.generate("broad", 2, envelope="heart", seed=3, node_budget=80, n_frames=30)
    b = api.generate("broad", 1, envelope="heart", seed=3, node_budget=80, n_frames=30)
    assert len(a) == 2 and all(t.nodes3d.shape[0] == 30 for t in a)
    assert a[0].meta["twigs"]["first_node"] <= 80 and a[0].meta["species"] == "broad" and a[0].meta["seed"] == 3
    np.testing.assert_array_equal(a[0].nodes3d, b[0].nodes3d)          # same seed, same tree
    assert a[0].n_nodes != a[1].n_nodes or not np.allclose(a[0].nodes3d[0], a[1].nodes3d[0])
    with pytest.raises(api.InputError, match="unknown generation setting"):
        api.generate("broad", 1, nodes=10)


def test_build_and_export_in_blender(tree, tmp_path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    built = api.build_tree(bpy.context, tree, "API oak")
    assert built["armature"].type == "ARMATURE" and built["collection"].name == "API oak"
    path = api.export(built, tmp_path / "oak.glb")
    doc, binary = read_glb(path)
    channels = doc["animations"][0]["channels"]
    rot = [c for c in channels if c["target"]["path"] == "rotation"]
    assert len(rot) >= tree.n_nodes - 1                                 # every branch bone animated
    times = accessor(doc, binary, doc["animations"][0]["samplers"][rot[0]["sampler"]]["input"])
    assert len(times) == tree.n_frames and times[0, 0] == pytest.approx(0.0)
    with pytest.raises(api.InputError, match="exists"):
        api.export(built, path)
    with pytest.raises(api.InputError, match="unknown export format"):
        api.export(built, tmp_path / "oak.obj")
    # a Tree3D exports through a temporary collection that is removed again
    n_coll = len(bpy.data.collections)
    fbx = api.export(tree, tmp_path / "oak.fbx")
    assert os.path.getsize(fbx) > 10_000 and len(bpy.data.collections) == n_coll
