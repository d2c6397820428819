"""The add-on registers, unregisters and registers again (bpy wheel, and inside real Blender)."""
import bpy

import tree_from_video


def _registered():
    return (hasattr(bpy.types, "TREE_OT_trace_skeleton") and hasattr(bpy.types, "TREE_PT_main")
            and hasattr(bpy.types.Scene, "tree_video"))


def test_register_unregister_register():
    tree_from_video.register()
    try:
        assert _registered()
        assert bpy.ops.tree_video.trace_skeleton.idname() == "TREE_OT_trace_skeleton"
        bpy.context.scene.tree_video.levels = 5
        tree_from_video.unregister()
        assert not _registered()
        tree_from_video.register()
        assert _registered()
        assert bpy.context.scene.tree_video.levels == 6   # fresh property group
    finally:
        tree_from_video.unregister()
    assert not _registered()


def test_operator_reports_bad_video_without_traceback(tmp_path):
    tree_from_video.register()
    try:
        props = bpy.context.scene.tree_video
        props.video_path = str(tmp_path / "missing.mp4")
        props.outline_path = str(tmp_path / "missing.json")
        props.output_dir = str(tmp_path / "out")
        result = bpy.ops.tree_video.trace_skeleton()
        assert result == {"CANCELLED"}
        assert not (tmp_path / "out").exists()
    finally:
        tree_from_video.unregister()
