"""The Export button (Tree sidebar › Export, File › Export): the selected trees or one picked from the
file's trees, each to its own file with only its own bones; plain refusals (file exists, relative
folder in an unsaved file, nothing to export); and the modal run — one tree per timer tick with
progress, Esc / Cancel leaving no file."""
import json
import os
import struct

import bpy
import numpy as np
import pytest

from trees import (
    addon,  # noqa: F401  (autouse fixture: the add-on registered per test)
    binary_tree,
    broad_tree,
)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]


def _modules():
    """The live add-on modules (unregister drops them from sys.modules, so import them per test)."""
    from tree_from_video.operators import export_op, jobs
    from tree_from_video.operators.scene import build, trees
    return export_op, jobs, build, trees


def _build(name, tree):
    return _modules()[2].build_tree(bpy.context, tree, name)


def _select(*colls):
    """Select exactly the objects of ``colls``; no active object."""
    bpy.context.view_layer.objects.active = None
    for ob in bpy.context.view_layer.objects:
        ob.select_set(False)
    for coll in colls:
        for ob in coll.all_objects:
            ob.select_set(True)


def _export():
    """Run Export blocking; a background Blender raises the reported error, the wheel returns CANCELLED."""
    try:
        return bpy.ops.tree_video.export("EXEC_DEFAULT")
    except RuntimeError:
        return {"CANCELLED"}


def glb_doc(path) -> dict:
    data = open(path, "rb").read()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    size, kind = struct.unpack_from("<II", data, 12)
    assert kind == 0x4E4F534A
    return json.loads(data[20:20 + size])


def glb_bones(path) -> list:
    """Names of the skin joints (the exported bones) of a GLB file."""
    doc = glb_doc(path)
    return sorted(doc["nodes"][j]["name"] for skin in doc["skins"] for j in skin["joints"])


@pytest.fixture
def two_trees(addon):
    """Two trees of different sizes: 'Small Oak' (31 bones) and 'Broad' (234 bones), nothing selected."""
    small = _build("Small Oak", binary_tree(31, frames=24))["collection"]
    broad = _build("Broad", broad_tree(24))["collection"]
    _select()
    return small, broad


def test_selected_tree_is_exported_with_its_bones_only(addon, two_trees, tmp_path):
    export_op, _, _, trees = _modules()
    small, broad = two_trees
    rig_bones = sorted(b.name for b in small.objects["Small Oak Rig"].data.bones)
    assert len(rig_bones) == 31 and len(broad.objects["Broad Rig"].data.bones) == 234
    assert [c.name for c in trees.file_trees()] == ["Broad", "Small Oak"]
    addon.output_dir, addon.export_format = str(tmp_path / "out"), "GLB"
    # nothing selected: disabled, and the poll says why
    assert not bpy.ops.tree_video.export.poll()
    assert export_op.why_not(bpy.context, addon).startswith("no tree selected; click a tree in the viewport")
    _select(small)
    bpy.context.view_layer.objects.active = small.objects["Small Oak Branches"]
    addon.collection_name = "Broad"                     # Output › Collection no longer chooses what is exported
    assert bpy.ops.tree_video.export.poll()
    assert _export() == {"FINISHED"}
    path = str(tmp_path / "out" / "Small_Oak.glb")
    assert sorted(os.listdir(tmp_path / "out")) == ["Small_Oak.glb"]
    assert glb_bones(path) == rig_bones                                # its 31 bones, none of Broad's 234
    assert export_op.LAST_EXPORT.paths == [path] and os.path.isabs(path)     # the absolute path is reported
    assert [ob.name for ob in bpy.context.selected_objects if ob.name.startswith("Broad")] == []   # selection kept
    # the panel then shows what was written first, and the file it just wrote as a note, not an error
    from test_panel_layout import draw

    from tree_from_video.ui import panel
    log = draw(panel.TREE_PT_export)
    labels = [e[2] for e in log if e[0] == "label"]
    first = next(k for k, e in enumerate(log) if e[0] == "label" and e[2].startswith("Last export: 1 file"))
    assert first < next(k for k, e in enumerate(log) if e[0] == "prop" and e[3] == "export_format")
    assert "Small_Oak.glb" in labels and "Just written: tick Overwrite to redo" in labels
    assert not any("exists" in t for t in labels)


def test_which_trees_selected_means(addon, two_trees):
    trees = _modules()[3]
    small, broad = two_trees
    layers = bpy.context.view_layer.layer_collection.children

    def names():
        return [c.name for c in trees.selected_trees(bpy.context)]
    _select(small, broad)
    assert names() == ["Broad", "Small Oak"]
    _select()
    assert names() == []                                # two trees, none pointed at
    bpy.context.view_layer.objects.active = broad.objects["Broad Rig"]
    assert names() == ["Broad"]                         # a new tree lands unselected, its rig active
    _select()
    bpy.context.view_layer.active_layer_collection = layers["Small Oak"]
    assert names() == ["Small Oak"]                     # a tree clicked in the Outliner
    bpy.context.view_layer.active_layer_collection = bpy.context.view_layer.layer_collection
    assert names() == []                                # the scene collection is not a forest
    bpy.data.collections.remove(broad)
    assert names() == ["Small Oak"]                     # the file's only tree


def test_two_selected_trees_write_two_files(addon, two_trees, tmp_path):
    export_op = _modules()[0]
    small, broad = two_trees
    _select(small, broad)
    addon.output_dir, addon.export_format = str(tmp_path), "GLB"
    addon.export_name = "ignored"                       # a typed name is for a single tree
    assert _export() == {"FINISHED"}
    assert sorted(os.listdir(tmp_path)) == ["Broad.glb", "Small_Oak.glb"]
    assert len(glb_bones(tmp_path / "Small_Oak.glb")) == 31
    assert len(glb_bones(tmp_path / "Broad.glb")) == 234
    assert export_op.LAST_EXPORT.paths == [str(tmp_path / "Broad.glb"), str(tmp_path / "Small_Oak.glb")]


def test_the_list_picks_a_generated_tree_or_a_forest(addon, tmp_path):
    from tree_from_video.ui import properties
    export_op, _, _, trees = _modules()
    assert not bpy.ops.tree_video.export.poll()
    assert export_op.why_not(bpy.context, addon).startswith("no tree in this file")
    addon.species_source, addon.species_name = "LIBRARY", "broad"
    addon.gen_frames, addon.gen_nodes, addon.forest_count = 24, 60, 2
    assert bpy.ops.tree_video.generate("EXEC_DEFAULT") == {"FINISHED"}
    generated = next(c for c in bpy.data.collections if trees.is_tree(c))
    assert bpy.ops.tree_video.generate_forest("EXEC_DEFAULT") == {"FINISHED"}
    forest = bpy.data.collections["Forest"]
    assert not trees.is_tree(forest) and len(trees.trees_in(forest)) == 2
    plain = bpy.data.collections.new("Not a tree")
    assert properties._holds_trees(None, generated) and properties._holds_trees(None, forest)
    assert not properties._holds_trees(None, plain)              # the list offers trees and forests only
    _select()
    addon.export_scope, addon.output_dir, addon.export_format = "PICK", str(tmp_path), "GLB"
    assert export_op.why_not(bpy.context, addon) == "no tree picked; choose one in the Tree list"
    addon.export_tree = generated
    addon.export_name = "my tree.glb"                   # typed, with the extension: kept as typed
    assert _export() == {"FINISHED"}
    rig = next(o for o in generated.objects if o.type == "ARMATURE")
    assert os.listdir(tmp_path) == ["my tree.glb"]
    assert glb_bones(tmp_path / "my tree.glb") == sorted(b.name for b in rig.data.bones)
    addon.export_tree, addon.export_format = forest, "FBX"      # a forest: one file per tree
    assert _export() == {"FINISHED"}
    assert sorted(os.listdir(tmp_path)) == ["Forest_000.fbx", "Forest_001.fbx", "my tree.glb"]
    _usd_of_a_leafy_tree(addon, export_op, generated, tmp_path)


def _usd_of_a_leafy_tree(addon, export_op, coll, folder):
    """USD through the renaming of the hidden temporary file: its leaf texture resolves (textures/)."""
    from tree_from_video.core.errors import InputError
    from tree_from_video.operators.scene import export
    addon.export_tree, addon.export_format, addon.export_name = coll, "USD", ""
    if not export.has_usd():
        with pytest.raises(InputError, match="built without USD; export FBX or glTF instead"):
            export_op.plan(bpy.context, addon)
        return
    assert any(o.name.endswith(" Leaves") for o in coll.objects)
    assert _export() == {"FINISHED"}
    usd = folder / f"{bpy.path.clean_name(coll.name)}.usdc"
    assert export_op.LAST_EXPORT.paths == [str(usd)]
    assert not [f for f in os.listdir(folder) if f.startswith(".")]          # no temporary file left
    assert [f for f in os.listdir(folder / "textures") if f.endswith(".png")]  # the leaf image beside it
    from pxr import Usd
    from test_exports import _validate_usd  # every validator, MissingReference included
    _validate_usd(Usd.Stage.Open(str(usd)))


def test_existing_file_is_refused_with_a_plain_message(addon, two_trees, tmp_path):
    from tree_from_video.core.errors import InputError
    export_op = _modules()[0]
    small, broad = two_trees
    _select(small)
    addon.output_dir, addon.export_format = str(tmp_path), "FBX"
    target = tmp_path / "Small_Oak.fbx"
    target.write_bytes(b"keep me")
    with pytest.raises(InputError) as err:
        export_op.plan(bpy.context, addon)
    assert str(err.value) == f"{target} exists: tick Overwrite or choose another name"
    assert _export() == {"CANCELLED"} and target.read_bytes() == b"keep me"
    _select(small, broad)                              # several files: the first that exists and how many
    (tmp_path / "Broad.fbx").write_bytes(b"keep me too")
    with pytest.raises(InputError) as err:
        export_op.plan(bpy.context, addon)
    assert str(err.value) == f"{tmp_path / 'Broad.fbx'} exists (and 1 more): tick Overwrite or choose another folder"
    addon.overwrite = True
    assert _export() == {"FINISHED"}
    assert target.stat().st_size > 1000 and (tmp_path / "Broad.fbx").stat().st_size > 1000
    assert sorted(os.listdir(tmp_path)) == ["Broad.fbx", "Small_Oak.fbx"]       # no temporary file left


def test_relative_folder_in_an_unsaved_file_is_refused(addon, two_trees, tmp_path, monkeypatch):
    from tree_from_video.core.errors import InputError
    export_op = _modules()[0]
    monkeypatch.chdir(tmp_path)                         # where a relative path used to land
    small, _ = two_trees
    _select(small)
    assert bpy.data.filepath == "" and addon.output_dir == "//tree_from_video"     # the default
    with pytest.raises(InputError) as err:
        export_op.plan(bpy.context, addon)
    assert str(err.value) == ("the folder '//tree_from_video' is relative to the .blend file, which is not saved yet; "
                              "save the file or choose an absolute folder")
    assert _export() == {"CANCELLED"} and os.listdir(tmp_path) == []
    addon.output_dir = "exports"                        # relative to the working folder: refused too
    assert _export() == {"CANCELLED"} and os.listdir(tmp_path) == []
    addon.output_dir = "//tree_from_video"
    (tmp_path / "scene").mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene" / "forest.blend"))
    addon = bpy.context.scene.tree_video
    _select(bpy.data.collections["Small Oak"])
    assert _export() == {"FINISHED"}                    # saved: // is beside the .blend
    assert os.listdir(tmp_path / "scene" / "tree_from_video") == ["Small_Oak.fbx"]


def test_file_export_menu_opens_the_same_export(addon, two_trees, tmp_path):
    export_op = _modules()[0]
    assert export_op.menu_export in bpy.types.TOPBAR_MT_file_export._dyn_ui_initialize()
    small, _ = two_trees
    _select(small)
    addon.output_dir, addon.export_format = str(tmp_path), "GLB"
    assert bpy.ops.tree_video.export_dialog("EXEC_DEFAULT") == {"FINISHED"}
    assert os.listdir(tmp_path) == ["Small_Oak.glb"]


# ----------------------------------------------------------------------------- the modal run

class _WindowManager:
    """What JobOperator's invoke/modal use of the window manager, recorded (no event loop here)."""

    def __init__(self):
        self.windows, self.flags, self.progress, self.timers = [], {}, [], 0
        self.tree_video_status, self.tree_video_progress = "", 0.0

    def event_timer_add(self, step, window=None):
        self.timers += 1
        return object()

    def event_timer_remove(self, timer):
        self.timers -= 1

    def modal_handler_add(self, op):
        return True

    def progress_begin(self, lo, hi):
        self.progress.append("begin")

    def progress_update(self, value):
        self.progress.append(value)

    def progress_end(self):
        self.progress.append("end")

    def get(self, key, default=None):
        return self.flags.get(key, default)

    def __contains__(self, key):
        return key in self.flags

    def __setitem__(self, key, value):
        self.flags[key] = value

    def __delitem__(self, key):
        del self.flags[key]


class _Context:
    def __init__(self, wm):
        self.window_manager, self.window = wm, None

    def __getattr__(self, name):
        return getattr(bpy.context, name)


class _Event:
    def __init__(self, kind):
        self.type = kind


def _driver():
    """The Export operator's job methods on a plain object (a registered Operator cannot be
    instantiated): invoke and modal run exactly as Blender calls them, minus the event loop."""
    export_op, jobs, _, _ = _modules()
    op_cls = export_op.TREE_OT_export

    class Driver(jobs.JobOperator):
        what, cancelled_note = op_cls.what, op_cls.cancelled_note
        make_job, done = op_cls.make_job, op_cls.done

        def __init__(self):
            self.reports = []

        def report(self, kind, message):
            self.reports.append((set(kind), message))
    return Driver()


def test_invoke_exports_tree_by_tree_with_progress(addon, tmp_path):
    colls = [_build(name, binary_tree(n, frames=24, seed=n))["collection"]
             for name, n in (("Ash", 15), ("Birch", 31), ("Cedar", 63))]
    _select(*colls)
    addon.output_dir, addon.export_format = str(tmp_path / "out"), "GLB"
    wm = _WindowManager()
    ctx, op = _Context(wm), _driver()
    assert op.invoke(ctx, _Event("NONE")) == {"RUNNING_MODAL"}
    assert wm.timers == 1 and os.listdir(tmp_path / "out") == []       # invoke returns before any export
    assert op.modal(ctx, _Event("MOUSEMOVE")) == {"PASS_THROUGH"}      # Blender stays usable
    seen, result = [], {"RUNNING_MODAL"}
    while result == {"RUNNING_MODAL"}:
        result = op.modal(ctx, _Event("TIMER"))
        seen.append((wm.tree_video_status, round(wm.tree_video_progress, 1),
                     len([f for f in os.listdir(tmp_path / "out") if f.endswith(".part.glb")])))
        assert len(seen) < 10
    assert result == {"FINISHED"}
    # one tree per tick; the status names the tree being exported; progress by bones × frames
    assert [s[0] for s in seen[:3]] == ["exporting 'Ash' (1/3)", "exporting 'Birch' (2/3)", "exporting 'Cedar' (3/3)"]
    assert [s[1] for s in seen[:3]] == [0.0, round(100 * 15 / 109, 1), round(100 * 46 / 109, 1)]
    assert [s[2] for s in seen] == [0, 1, 2, 0]        # hidden temporary files until the last tree is done
    assert wm.tree_video_status == "" and wm.progress[0] == "begin" and wm.progress[-1] == "end" and wm.timers == 0
    names = ["Ash.glb", "Birch.glb", "Cedar.glb"]
    assert sorted(os.listdir(tmp_path / "out")) == names
    paths = [str(tmp_path / "out" / n) for n in names]
    # one status line that fits, whatever the count: the count and the folder (the panel lists them)
    (level, message), = op.reports
    export_op = _modules()[0]
    total = export_op.LAST_EXPORT.total
    assert message == f"exported 3 files to {tmp_path / 'out'} in {total:.0f} s (Export panel: Last export)"
    # the time per tree and in all, for the panel: each tree's writer time, their sum within the whole
    took = export_op.LAST_EXPORT.seconds
    assert len(took) == 3 and all(t > 0 for t in took) and sum(took) <= total
    assert export_op.LAST_EXPORT.timing() == f"{total:.0f} s in all, {min(took):.1f}–{max(took):.1f} s a tree"
    assert [len(glb_bones(p)) for p in paths] == [15, 31, 63]


@pytest.mark.parametrize("how", ["ESC", "Cancel button"])
def test_cancelling_the_modal_export_leaves_no_file(addon, tmp_path, how):
    export_op, jobs, _, _ = _modules()
    colls = [_build(name, binary_tree(15, frames=12, seed=k))["collection"] for k, name in enumerate(("Ash", "Birch"))]
    _select(*colls)
    old = tmp_path / "Ash.glb"
    old.write_bytes(b"the user's file")
    addon.output_dir, addon.export_format, addon.overwrite = str(tmp_path), "GLB", True
    wm = _WindowManager()
    ctx, op = _Context(wm), _driver()
    assert op.invoke(ctx, _Event("NONE")) == {"RUNNING_MODAL"}
    assert jobs.running() and not bpy.ops.tree_video.export.poll()     # one export at a time
    assert op.modal(ctx, _Event("TIMER")) == {"RUNNING_MODAL"}         # stage 1/2 shown
    assert op.modal(ctx, _Event("TIMER")) == {"RUNNING_MODAL"}         # Ash exported to a temporary file
    assert len(os.listdir(tmp_path)) == 2
    if how == "ESC":
        result = op.modal(ctx, _Event("ESC"))
    else:
        assert bpy.ops.tree_video.cancel.poll()
        jobs.request_cancel(ctx)
        result = op.modal(ctx, _Event("TIMER"))
    assert result == {"CANCELLED"}
    assert os.listdir(tmp_path) == ["Ash.glb"] and old.read_bytes() == b"the user's file"
    assert op.reports == [({"INFO"}, "export cancelled; no file written")]
    assert not jobs.running() and wm.tree_video_status == "" and wm.timers == 0 and not wm.flags
    assert export_op.LAST_EXPORT.paths == []


def test_background_exports_share_the_trees_by_size():
    """export_process.split: every tree in exactly one process, in its order, the largest first to
    the lightest; the two totals as even as a greedy split makes them."""
    from tree_from_video.operators.scene.export_process import split
    assert split([5.0, 1, 1, 1, 1, 1], 2) == [[0], [1, 2, 3, 4, 5]]
    assert split([3.0, 3, 2, 2, 2], 2) == [[0, 2, 4], [1, 3]]          # 7 and 5
    assert split([1.0], 2) == [[0]]                                    # one tree: one process
    sizes = [float(s) for s in np.random.default_rng(0).integers(100, 1000, 12)]
    parts = split(sizes, 2)
    assert sorted(i for p in parts for i in p) == list(range(12)) and all(p == sorted(p) for p in parts)
    totals = [sum(sizes[i] for i in p) for p in parts]
    assert abs(totals[0] - totals[1]) <= max(sizes)
