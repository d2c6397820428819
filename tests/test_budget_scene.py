"""A bone budget built in Blender (issue 33): the armature holds the kept bones, each vertex one
group, and Blender's own evaluated pose bones stand where the re-fitted rig says at every frame
checked (location and rotation keys, not-connected bones); the GLB carries that many joints."""
import bpy
import numpy as np
import pytest
from test_budget import _pose_world
from test_exports import read_glb

from tree_from_video import api
from tree_from_video.core.asset import tree_asset
from tree_from_video.operators.scene import build, export

from trees import empty_scene  # noqa: F401  (autouse fixture)

pytestmark = [pytest.mark.blender]


def test_a_budget_rig_plays_in_blender_as_fitted(tmp_path):
    tree, = api.generate("broad", node_budget=80, n_frames=24, seed=6)
    built = build.build_tree(bpy.context, tree, "Game", bone_budget=32)
    rig = built["armature"]
    asset = tree_asset(tree, bone_budget=32)
    assert built["budget"] == asset.budget and len(rig.data.bones) == len(asset.rig.names) <= 32
    for ob in (built["mesh"], built["leaves"]):
        counts = np.array([len(v.groups) for v in ob.data.vertices])
        assert (counts == 1).all()                                     # one influence, weight 1
    W = _pose_world(asset.rig)
    M = np.tile(np.eye(4), (len(asset.rig.names), 1, 1))
    M[:, :3, :3], M[:, :3, 3] = asset.rig.rest, asset.rig.head
    for f in (0, 7, 23):
        bpy.context.scene.frame_set(f + 1)
        got = np.array([np.array(rig.pose.bones[n].matrix) for n in asset.rig.names])
        want = W[f] @ M
        assert np.abs(got - want).max() < 1e-4, f"frame {f}"
    doc, _ = read_glb(export.export_gltf(tmp_path / "game.glb", [rig, built["mesh"], built["leaves"]]))
    assert len(doc["skins"][0]["joints"]) == len(asset.rig.names)
