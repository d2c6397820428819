"""Generate never cuts what is already in the scene: a reconstruction sets the scene's frame rate
and range; a generated tree or a forest added to it only grows the range to cover itself, plays at
the scene's rate, and by default lasts as long as the scene's range."""
import bpy
import pytest

from trees import (
    binary_tree,
    empty_scene,  # noqa: F401  (autouse: a fresh scene per test)
    registered,  # noqa: F401  (autouse: the add-on registered)
)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

LONG = 300          # frames of the "reconstruction" (the real clip had 555)


def _reconstruction():
    from tree_from_video.operators.scene.build import build_tree
    return build_tree(bpy.context, binary_tree(63, LONG, 30.0, seed=1), "Reconstruction")


def _generate_props(frames: int = 0):
    p = bpy.context.scene.tree_video
    p.species_source, p.envelope_source = "LIBRARY", "CIRCLE"
    p.species_name = "broad"
    p.gen_frames, p.gen_nodes, p.gen_height = frames, 60, 6.0
    p.build_leaves = False
    return p


def _rig_frames(coll) -> int:
    from tree_from_video.operators.scene.action_api import action_fcurves
    rig = next(o for o in coll.all_objects if o.type == "ARMATURE")
    return int(round(max(fc.range()[1] for fc in action_fcurves(rig.animation_data.action))))   # keys from frame 1


def _new_tree_collections(before: set):
    return [c for c in bpy.data.collections if c.name not in before and any(o.type == "ARMATURE" for o in c.objects)]


def test_the_first_tree_sets_the_scenes_rate_and_range():
    scene = bpy.context.scene
    scene.render.fps, scene.frame_start, scene.frame_end = 24, 1, 250
    _reconstruction()
    assert (scene.render.fps, scene.frame_start, scene.frame_end) == (30, 1, LONG)


def test_generate_keeps_the_reconstructions_range_and_rate():
    scene = bpy.context.scene
    _reconstruction()
    _generate_props()
    before = {c.name for c in bpy.data.collections}
    assert bpy.ops.tree_video.generate("EXEC_DEFAULT") == {"FINISHED"}
    assert (scene.frame_start, scene.frame_end) == (1, LONG)         # was cut to the species' 180
    assert scene.render.fps == 30 and scene.render.fps_base == 1.0
    new = _new_tree_collections(before)
    assert len(new) == 1 and _rig_frames(new[0]) == LONG               # as long as the scene's range


def test_a_longer_generated_tree_grows_the_range_and_a_user_range_is_kept_where_it_covers():
    scene = bpy.context.scene
    _reconstruction()
    _generate_props(frames=LONG + 100)
    assert bpy.ops.tree_video.generate("EXEC_DEFAULT") == {"FINISHED"}
    assert (scene.frame_start, scene.frame_end) == (1, LONG + 100)
    scene.frame_end = 800                                              # the user's longer range stays
    _generate_props(frames=120)
    assert bpy.ops.tree_video.generate("EXEC_DEFAULT") == {"FINISHED"}
    assert (scene.frame_start, scene.frame_end) == (1, 800)


def test_a_forest_beside_a_reconstruction_keeps_its_range():
    scene = bpy.context.scene
    _reconstruction()
    p = _generate_props()
    p.forest_count, p.forest_spacing = 2, 6.0
    assert bpy.ops.tree_video.generate_forest("EXEC_DEFAULT") == {"FINISHED"}
    assert (scene.frame_start, scene.frame_end, scene.render.fps) == (1, LONG, 30)
