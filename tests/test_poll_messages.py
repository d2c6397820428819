"""Every disabled button says why: each operator's poll refuses with a message (Blender shows it as
the greyed-out button's tooltip; a script calling the operator gets it in the RuntimeError), and
passes once the reason is gone."""
import os

import bpy
import pytest

from tree_from_video.operators import jobs

from samples import committed
from trees import addon  # noqa: F401  (autouse fixture: the add-on registered per test)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

VIDEO = os.path.join(committed("broad"), "video.mp4")
OUTLINE = os.path.join(committed("broad"), "outline.json")


class _Unfinished:
    done = False


def refused(op_name: str) -> str:
    """The poll message of ``bpy.ops.tree_video.<op_name>`` (asserting that it refuses)."""
    op = getattr(bpy.ops.tree_video, op_name)
    assert op.poll() is False, f"{op_name} is enabled"
    with pytest.raises(RuntimeError) as err:
        op()
    text = str(err.value)
    assert text.startswith(f"Operator bpy.ops.tree_video.{op_name}.poll()"), text
    return text.split(".poll()", 1)[1].strip()


def test_reconstruct_and_preview_say_what_is_missing(addon, tmp_path):
    for op in ("reconstruct", "preview"):
        addon.video_path, addon.outline_path, addon.outline_source = "", OUTLINE, "FILE"
        assert refused(op) == "no video chosen; pick one in the Source panel"
        addon.video_path = str(tmp_path / "typo.mp4")
        assert refused(op) == f"video '{tmp_path / 'typo.mp4'}' does not exist; check the path in the Source panel"
        addon.video_path, addon.outline_path = VIDEO, ""
        assert refused(op) == "no outline file chosen; pick one in the Outline panel"
        addon.outline_path = str(tmp_path / "none.json")
        assert "outline file" in refused(op) and "does not exist" in refused(op)
        addon.outline_source = "MASK"
        assert refused(op).startswith("no outline mask chosen; press Open Clip to Draw Outline")
        addon.outline_source = "ANNOTATION"
        assert refused(op).startswith("no outline yet (No clip of this video is open)")
        addon.outline_source, addon.outline_path = "FILE", OUTLINE
        assert getattr(bpy.ops.tree_video, op).poll()
        jobs._RUNNING.add(job := _Unfinished())
        try:
            assert refused(op) == "a job is running; wait for it to finish or press Cancel"
        finally:
            jobs._RUNNING.discard(job)
        addon.outline_source = "AUTO"                      # needs no outline
        assert getattr(bpy.ops.tree_video, op).poll()


def test_cancel_open_clip_and_trace_skeleton_say_why(addon):
    assert refused("cancel") == "nothing is running"
    addon.video_path = ""
    assert refused("open_clip") == "no video chosen; pick one in the Source panel"
    assert refused("trace_skeleton") == "no video chosen; pick one in the Source panel"
    addon.video_path, addon.outline_path = VIDEO, ""
    assert bpy.ops.tree_video.open_clip.poll()
    assert refused("trace_skeleton") == "no outline file chosen; pick one in the Outline panel"
    addon.outline_path = OUTLINE
    assert bpy.ops.tree_video.trace_skeleton.poll()


@pytest.mark.parametrize("op", ["generate", "generate_forest"])
def test_generate_says_which_species_or_shape_is_missing(addon, tmp_path, op):
    assert getattr(bpy.ops.tree_video, op).poll()          # the library species in a circle
    addon.species_source, addon.species_path = "FILE", ""
    assert refused(op) == "no species file chosen; pick one in the Generate panel"
    addon.species_path = str(tmp_path / "oak.json")
    assert "species file" in refused(op) and "does not exist" in refused(op)
    addon.species_source = "RECONSTRUCTION"
    assert refused(op).startswith("the species of a reconstructed tree needs a reconstruction in this file; "
                                  "press Reconstruct first")
    addon.species_source, addon.envelope_source = "LIBRARY", "SOURCE"
    assert refused(op).startswith("Source Outline needs a reconstruction in this file")
    addon.envelope_source = "CURVE"
    assert refused(op).startswith("no envelope curve chosen")
    addon.envelope_source, addon.envelope_image = "IMAGE", str(tmp_path / "heart.png")
    assert "silhouette image" in refused(op) and "does not exist" in refused(op)
    addon.envelope_source, addon.gen_audio = "CIRCLE", str(tmp_path / "storm.wav")
    assert "wind audio" in refused(op) and "does not exist" in refused(op)
    addon.gen_audio = ""
    jobs._RUNNING.add(job := _Unfinished())
    try:
        assert refused(op) == "a job is running; wait for it to finish or press Cancel"
    finally:
        jobs._RUNNING.discard(job)
    assert getattr(bpy.ops.tree_video, op).poll()


def test_save_species_and_export_without_a_tree_say_so(addon):
    assert "Reconstruct a tree first" in refused("save_species")
    assert "no tree" in refused("export")


def test_a_forest_being_built_keeps_the_other_buttons_greyed(addon):
    """Issue 32: between growing a forest (the worker) and building its trees (a few per tick on the
    main thread) the job left the running jobs, so every other button came back. The build phase
    now holds a ``jobs.Busy`` (generate_op.TREE_OT_generate_forest.done) until its last tree."""
    busy = jobs.hold(jobs.Busy())
    try:
        assert jobs.running()
        for op in ("reconstruct", "generate", "generate_forest"):
            assert refused(op) == "a job is running; wait for it to finish or press Cancel", op
    finally:
        jobs._RUNNING.discard(busy)
    assert not jobs.running()
