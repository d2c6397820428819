"""A loop in Blender and its exports (issue 33): the rig's action is named ``<tree>_loop``, the GLB's
animation and the FBX's take carry that name (Godot loops an animation whose name ends in "loop"),
and the exported clip's last key is its first, one loop period after it."""
import os

import bpy
import numpy as np
import pytest
from test_exports import accessor, read_glb

from tree_from_video import api
from tree_from_video.core.loop import loop_tree
from tree_from_video.operators.scene import build, export

from trees import empty_scene  # noqa: F401  (autouse fixture)

pytestmark = [pytest.mark.blender]


@pytest.fixture(scope="module")
def looped():
    tree, = api.generate("broad", node_budget=40, n_frames=60, seed=3)
    return loop_tree(tree, 1.5)


def test_a_loop_exports_as_a_named_loop(looped, tmp_path):
    tree, cut = looped
    built = build.build_tree(bpy.context, tree, "Oak")
    assert built["action"].name == "Oak_loop"
    objects = [built["armature"], built["mesh"], built["leaves"]]
    glb = export.export_gltf(tmp_path / "oak.glb", objects)
    doc, binary = read_glb(glb)
    anim, = doc["animations"]
    assert anim["name"] == "Oak_loop"
    times = accessor(doc, binary, anim["samplers"][0]["input"])[:, 0]
    assert len(times) == cut.frames + 1 and times[-1] == pytest.approx(cut.frames / tree.fps, abs=1e-4)
    for ch in anim["channels"]:                   # every bone ends where it started: the loop closes
        if ch["target"]["path"] == "rotation":
            q = accessor(doc, binary, anim["samplers"][ch["sampler"]]["output"])
            assert abs(abs(float(np.dot(q[0], q[-1]))) - 1.0) < 1e-5
    fbx = export.export_fbx(tmp_path / "oak.fbx", objects)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.fbx(filepath=str(fbx))
    takes = [a.name for a in bpy.data.actions]
    assert any(name.endswith("|Oak_loop") for name in takes), takes     # Blender names it "<object>|<take>"


def test_a_tree_without_a_loop_keeps_its_sway_name(tmp_path):
    tree, = api.generate("broad", node_budget=30, n_frames=12, seed=4)
    built = build.build_tree(bpy.context, tree, "Ash")
    assert built["action"].name == "Ash Sway"
    doc, _ = read_glb(export.export_gltf(tmp_path / "ash.glb", [built["armature"], built["mesh"]]))
    assert doc["animations"][0]["name"] == "Ash Sway"                 # was "Animation"


def test_the_panels_loop_cuts_generated_trees_and_forests(tmp_path):
    """Output › Loop: Generate and Generate Forest build loops (the scene's range the loop's L + 1
    frames); 0 keeps the clip as grown."""
    import tree_from_video as pkg
    pkg.register()
    try:
        props = bpy.context.scene.tree_video
        props.species_source, props.species_name = "LIBRARY", "broad"
        props.gen_frames, props.gen_nodes, props.loop_seconds = 60, 60, 1.0
        assert bpy.ops.tree_video.generate("EXEC_DEFAULT") == {"FINISHED"}
        rig = next(o for o in bpy.data.objects if o.type == "ARMATURE")
        action = rig.animation_data.action
        assert action.name.endswith("_loop")
        fps = bpy.context.scene.render.fps
        assert bpy.context.scene.frame_end == round(1.0 * fps) + 1
        props.forest_count = 2
        assert bpy.ops.tree_video.generate_forest("EXEC_DEFAULT") == {"FINISHED"}
        forest = [o for o in bpy.data.objects if o.type == "ARMATURE" and o.name.startswith("Forest")]
        assert len(forest) == 2 and all(o.animation_data.action.name.endswith("_loop") for o in forest)
    finally:
        pkg.unregister()


def test_the_batchs_loop_is_checked_before_any_work(tmp_path, capsys):
    from tree_from_video import cli
    base = ["--generate", "1", "--species", "broad", "--out", str(tmp_path / "g")]
    assert cli.main(base + ["--loop", "-2", "--gltf"]) == 2
    assert "--loop -2.0: give a number of seconds" in capsys.readouterr().err
    assert cli.main(base + ["--loop", "4"]) == 2
    assert "--loop cuts the animation of the Blender outputs; add one of --fbx" in capsys.readouterr().err
    assert not os.path.exists(tmp_path / "g")
