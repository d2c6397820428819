"""The add-on registers, unregisters and registers again (bpy wheel, and inside real Blender)."""
import bpy
import pytest

import tree_from_video

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]


def _classes():
    from tree_from_video.operators import generate_op, reconstruct_op, skeleton_op
    from tree_from_video.ui import panel, properties
    return skeleton_op.classes + reconstruct_op.classes + generate_op.classes + panel.classes + properties.classes


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


def test_panel_labels_and_operators_are_registered():
    from tree_from_video.operators import reconstruct_op
    from tree_from_video.ui import panel
    tree_from_video.register()
    try:
        view3d = [c for c in panel.classes if c.bl_space_type == "VIEW_3D"]
        clip = [c for c in panel.classes if c.bl_space_type == "CLIP_EDITOR"]     # Track & Preview's sidebar
        assert {c.bl_label for c in view3d} == {"Tree from Video", "Source", "Outline", "Reconstruction", "Output",
                                                "Game Export", "Generate", "Export"}
        assert {c.bl_label for c in clip} == {"Tree from Video", "Source", "Outline"} and len(view3d) + len(clip) == \
            len(panel.classes)
        assert all(c.is_registered and c.bl_category == "Tree" and c.bl_region_type == "UI" for c in panel.classes)
        assert all(c.bl_parent_id == "TREE_PT_main" for c in view3d if c is not panel.TREE_PT_main)
        assert all(c.bl_parent_id == "TREE_PT_clip_main" for c in clip if c is not panel.TREE_PT_clip_main)
        for idname in ("tree_video.reconstruct", "tree_video.preview", "tree_video.cancel", "tree_video.open_clip",
                       "tree_video.export", "tree_video.generate", "tree_video.generate_forest",
                       "tree_video.save_species",
                       "tree_video.trace_skeleton"):
            mod, name = idname.split(".")
            assert hasattr(getattr(bpy.ops, mod), name)
        assert {c.bl_idname for c in reconstruct_op.classes} >= {"tree_video.reconstruct", "tree_video.cancel"}
        # every setting has a tooltip
        props = bpy.context.scene.tree_video.bl_rna.properties
        assert all(p.description for p in props if p.identifier not in ("rna_type", "name"))
    finally:
        tree_from_video.unregister()


def test_cli_command_runs_the_batch_job(tmp_path):
    """``blender -c tree_from_video ...`` calls this; exit codes as batch.py."""
    import os

    from samples import committed
    tree_from_video.register()
    try:
        assert tree_from_video._cli_handle is not None
        assert tree_from_video._cli(["--help"]) == 0
        assert tree_from_video._cli(["/nope.mp4", "--outline", "x.json", "--out", str(tmp_path / "o")]) == 2
        folder = committed("broad")
        code = tree_from_video._cli([os.path.join(folder, "video.mp4"), "--outline",
                                     os.path.join(folder, "outline.json"), "--out", str(tmp_path / "ok"),
                                     "--frames", "0:24", "--no-video", "--quiet"])
        assert code == 0 and (tmp_path / "ok" / "tree3d.npz").exists()
    finally:
        tree_from_video.unregister()
    assert tree_from_video._cli_handle is None


def test_missing_dependencies_show_a_panel_naming_the_wheel(monkeypatch, capsys):
    import importlib.util

    from tree_from_video.ui import missing_deps
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "cv2" else real(name, *a))
    tree_from_video.register()
    try:
        assert missing_deps.TREE_PT_missing.is_registered
        assert missing_deps.TREE_PT_missing.missing == ["opencv-contrib-python-headless"]
        assert "missing opencv-contrib-python-headless" in capsys.readouterr().out
        assert not hasattr(bpy.types.Scene, "tree_video")          # nothing half-registered
    finally:
        tree_from_video.unregister()
    assert not missing_deps.TREE_PT_missing.is_registered
    monkeypatch.undo()
    tree_from_video.register()                                      # and it recovers once they exist
    try:
        assert _registered()
    finally:
        tree_from_video.unregister()


def test_presets_save_and_restore_settings():
    import os

    from tree_from_video.ui import presets
    tree_from_video.register()
    path = None
    try:
        props = bpy.context.scene.tree_video
        props.levels, props.form, props.solver, props.height_m = 7, "palm", "deterministic", 23.0
        assert bpy.ops.tree_video.preset_add(name="Test Spruce") == {"FINISHED"}
        folder = bpy.utils.user_resource("SCRIPTS", path=os.path.join("presets", presets.PRESET_SUBDIR))
        path = os.path.join(folder, presets.TREE_OT_preset_add.as_filename("Test Spruce") + ".py")
        assert os.path.isfile(path)
        text = open(path).read()
        assert "bpy.context.scene.tree_video.levels = 7" in text and "video_path" not in text
        props.levels, props.form, props.solver, props.height_m = 5, "auto", "probabilistic", 10.0
        bpy.ops.script.execute_preset(filepath=path, menu_idname="TREE_MT_presets")
        assert (props.levels, props.form, props.solver, props.height_m) == (7, "palm", "deterministic", 23.0)
    finally:
        if path and os.path.exists(path):
            os.unlink(path)
        tree_from_video.unregister()
