"""The add-on registers, unregisters and registers again (bpy wheel, and inside real Blender)."""
import bpy

import tree_from_video


def _classes():
    from tree_from_video.operators import reconstruct_op, skeleton_op
    from tree_from_video.ui import panel, properties
    return skeleton_op.classes + reconstruct_op.classes + panel.classes + properties.classes


def _registered():
    states = {c.is_registered for c in _classes()} | {hasattr(bpy.types.Scene, "tree_video")}
    assert len(states) == 1, "half registered"
    return states.pop()


def test_register_unregister_register():
    tree_from_video.register()
    try:
        assert _registered()
        assert bpy.ops.tree_video.trace_skeleton.idname() == "TREE_VIDEO_OT_trace_skeleton"
        bpy.context.scene.tree_video.levels = 5
        tree_from_video.unregister()
        assert not _registered()
        tree_from_video.register()
        assert _registered()
        assert bpy.context.scene.tree_video.levels == 5   # settings live in the scene: they survive a reload
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
        # the wheel returns CANCELLED; a real Blender in background raises the reported error
        try:
            result = bpy.ops.tree_video.trace_skeleton()
            assert result == {"CANCELLED"}
        except RuntimeError as exc:
            assert "does not exist; check the path" in str(exc)
            assert "Traceback" not in str(exc)
        assert not (tmp_path / "out").exists()
    finally:
        tree_from_video.unregister()
