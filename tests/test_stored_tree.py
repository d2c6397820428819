"""What the add-on keeps in the .blend (issue 20, items 4 and 5): a reconstructed tree and its clip
overlay survive saving and reopening the file; Save Species, Generate and the source outline work
on the selected one of several trees; Track & Preview loads the video's clip on its first frame
with the overlay kept in the file."""
import json
import os
import time

import bpy
import numpy as np
import pytest
import report

from tree_from_video.core.generate import species
from tree_from_video.core.keys import KEY_TOLERANCE
from tree_from_video.core.tree3d import tree_bytes, tree_from_bytes

from samples import committed
from trees import addon, binary_tree, broad_tree  # noqa: F401  (addon: autouse fixture)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

VIDEO = os.path.join(committed("broad"), "video.mp4")
OUTLINE = os.path.join(committed("broad"), "outline.json")


def _mods():
    """The add-on's modules as they are now (unregistering drops them from sys.modules)."""
    from tree_from_video.operators.scene import clip_overlay, stored
    return stored, clip_overlay


def _reconstruct(props, name: str, frames: tuple[int, int]):
    props.video_path, props.outline_path = VIDEO, OUTLINE
    props.use_frame_range, (props.frame_start, props.frame_end) = True, frames
    props.collection_name, props.build_leaves, props.twig_depth = name, False, 0
    assert bpy.ops.tree_video.reconstruct("EXEC_DEFAULT") == {"FINISHED"}
    return bpy.data.collections[name]


def _select(coll):
    """Click the tree's rig: it becomes the active object, the only one selected."""
    for ob in bpy.context.view_layer.objects:
        ob.select_set(False)
    rig = next(o for o in coll.objects if o.type == "ARMATURE")
    rig.select_set(True)
    bpy.context.view_layer.objects.active = rig


def _select_nothing():
    for ob in bpy.context.view_layer.objects:
        ob.select_set(False)
    bpy.context.view_layer.objects.active = None
    vl = bpy.context.view_layer
    vl.active_layer_collection = vl.layer_collection


def _reopen(path) -> None:
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))


def test_tree_bytes_round_trip_exactly():
    tree = broad_tree(40)
    tree.meta = {"height_px": 288.0, "envelope": {"z": [0.0, 1.0], "centre": [0.0, 0.0], "radius": [1.0, 2.0]}}
    back = tree_from_bytes(tree_bytes(tree))
    assert np.array_equal(back.nodes3d, tree.nodes3d) and np.array_equal(back.parents, tree.parents)
    assert np.array_equal(back.radius, tree.radius) and back.fps == tree.fps and back.name == tree.name
    assert back.meta["envelope"] == tree.meta["envelope"]


def test_a_reopened_file_keeps_the_tree_its_species_and_its_overlay(addon, tmp_path):
    stored, clip_overlay = _mods()
    coll = _reconstruct(addon, "Oak", (1, 30))
    kept = stored.load_tree(coll)
    assert kept.n_frames == 30 and kept.name == "Oak"
    rig = next(o for o in coll.objects if o.type == "ARMATURE")
    bpy.context.scene.frame_set(12)               # the stored tree is the one built: frame 12's bone tails
    mw = np.array(rig.matrix_world)
    tails = np.array([pb.tail for pb in rig.pose.bones if pb.name.startswith("B")]) @ mw[:3, :3].T + mw[:3, 3]
    child = np.array([int(pb.name[1:]) for pb in rig.pose.bones if pb.name.startswith("B")])
    H = float(np.ptp(kept.nodes3d[0][:, 2]))       # the curves play it within their tolerance (core/keys.py)
    assert np.abs(tails - kept.nodes3d[11][child]).max() <= KEY_TOLERANCE * H + 1e-4
    expected = species.fit_species(kept, "oak")
    geometry = clip_overlay.frame_geometry(VIDEO, 7)
    assert geometry is not None and len(geometry[0]) > 100
    nodes_before = kept.nodes3d.copy()

    _reopen(tmp_path / "tree.blend")

    stored, clip_overlay = _mods()
    assert clip_overlay.on_load_post in bpy.app.handlers.load_post
    coll = bpy.data.collections["Oak"]
    back = stored.load_tree(coll)
    assert np.array_equal(back.nodes3d, nodes_before) and back.nodes3d.dtype == np.float32
    pts, seg = clip_overlay.frame_geometry(VIDEO, 7)
    np.testing.assert_array_equal(pts, geometry[0])
    np.testing.assert_array_equal(seg, geometry[1])
    # Save Species and its panel line work on the reopened tree, with nothing selected
    _select_nothing()
    assert bpy.ops.tree_video.save_species.poll()
    assert stored.selected(bpy.context) == (coll, "the only one in the file")
    path = tmp_path / "oak.json"
    assert bpy.ops.tree_video.save_species(filepath=str(path)) == {"FINISHED"}
    model = species.load_species(path)
    assert model.n_bifurcations == expected.n_bifurcations and model.n_frames == 30
    saved, fitted = json.loads(path.read_text()), expected.to_json()
    assert saved["shape"] == fitted["shape"] and saved["motion"] == fitted["motion"]     # the same fit, exactly
    # Generate from it: the source outline and the species of the reopened tree
    props = bpy.context.scene.tree_video
    props.species_source, props.envelope_source, props.gen_nodes, props.gen_frames = "RECONSTRUCTION", "SOURCE", 80, 12
    assert bpy.ops.tree_video.generate() == {"FINISHED"}
    assert len(stored.tree_collections()) == 1              # a generated tree is not a reconstruction


def test_with_two_trees_the_selected_one_is_used(addon, tmp_path):
    stored, _ = _mods()
    oak = _reconstruct(addon, "Oak", (1, 30))
    elm = _reconstruct(addon, "Elm", (1, 24))
    _reopen(tmp_path / "two.blend")
    stored, _ = _mods()
    oak, elm = bpy.data.collections["Oak"], bpy.data.collections["Elm"]
    _select_nothing()
    assert not bpy.ops.tree_video.save_species.poll()
    assert stored.selected(bpy.context) == (None, "Select one of the 2 reconstructed trees")
    props = bpy.context.scene.tree_video
    props.species_source, props.gen_nodes, props.gen_frames = "RECONSTRUCTION", 80, 12
    with pytest.raises(RuntimeError, match="2 reconstructed trees; select"):
        bpy.ops.tree_video.generate()
    for k, (coll, frames) in enumerate(((oak, 30), (elm, 24), (oak, 30))):
        _select(coll)
        path = tmp_path / f"{coll.name}-{k}.json"
        assert bpy.ops.tree_video.save_species(filepath=str(path)) == {"FINISHED"}
        assert species.load_species(path).n_frames == frames
    # the active collection (clicked in the Outliner) picks a tree too
    _select_nothing()
    vl = bpy.context.view_layer
    vl.active_layer_collection = vl.layer_collection.children["Elm"]
    assert stored.selected(bpy.context)[0] == elm
    _select(elm)
    assert bpy.ops.tree_video.generate() == {"FINISHED"}


def test_track_and_preview_loads_the_clip_on_its_first_frame_and_keeps_the_overlay(addon, tmp_path):
    stored, clip_overlay = _mods()
    addon.video_path, addon.outline_path = VIDEO, OUTLINE
    addon.use_frame_range, addon.frame_start, addon.frame_end = True, 11, 40
    bpy.context.scene.frame_set(77)
    assert bpy.ops.tree_video.preview("EXEC_DEFAULT") == {"FINISHED"}
    clips = list(bpy.data.movieclips)
    assert len(clips) == 1 and os.path.samefile(bpy.path.abspath(clips[0].filepath), VIDEO)
    assert bpy.context.scene.frame_current == 11                # clip frame 11 = video frame 10, the first previewed
    assert clip_overlay.owners(VIDEO) == [bpy.context.scene]                # kept in the file with the scene
    assert clip_overlay.frame_geometry(VIDEO, 10) is None and clip_overlay.frame_geometry(VIDEO, 11) is not None
    addon.frame_start = 1
    assert bpy.ops.tree_video.preview("EXEC_DEFAULT") == {"FINISHED"}
    assert len(bpy.data.movieclips) == 1 and bpy.context.scene.frame_current == 1   # the same clip, frame 1
    pts, seg = clip_overlay.frame_geometry(VIDEO, 1)
    _reopen(tmp_path / "preview.blend")
    _, clip_overlay = _mods()
    again = clip_overlay.frame_geometry(VIDEO, 1)
    np.testing.assert_array_equal(again[0], pts)
    np.testing.assert_array_equal(again[1], seg)
    # the clip editor's sidebar has the same panels (same draw code) on the Tree tab
    for clip_panel, view_panel in (("TREE_PT_clip_main", "TREE_PT_main"), ("TREE_PT_clip_source", "TREE_PT_source"),
                                   ("TREE_PT_clip_outline", "TREE_PT_outline")):
        cls, base = (bpy.types.Panel.bl_rna_get_subclass_py(name) for name in (clip_panel, view_panel))
        assert (cls.bl_space_type, cls.bl_region_type, cls.bl_category) == ("CLIP_EDITOR", "UI", "Tree")
        assert cls.draw is base.draw


def test_storage_cost_of_a_long_tree(addon, tmp_path):
    """A 555-frame × 300-node tree (the issue's clip): what keeping it costs in time and file size."""
    from tree_from_video.operators.scene.build import build_tree
    stored, _ = _mods()
    tree = binary_tree(299, frames=555)
    build_tree(bpy.context, tree, "Long", mesh=False, leaves=False)
    coll = bpy.data.collections["Long"]
    bare = tmp_path / "bare.blend"
    t0 = time.perf_counter()
    bpy.ops.wm.save_as_mainfile(filepath=str(bare))
    t_bare = time.perf_counter() - t0
    t0 = time.perf_counter()
    stored.store_tree(coll, tree, VIDEO)
    t_store = time.perf_counter() - t0
    path = tmp_path / "kept.blend"
    t0 = time.perf_counter()
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    t_save = time.perf_counter() - t0
    t0 = time.perf_counter()
    bpy.ops.wm.open_mainfile(filepath=str(path))
    t_open = time.perf_counter() - t0
    stored, _ = _mods()
    t0 = time.perf_counter()
    back = stored.load_tree(bpy.data.collections["Long"])
    t_load = time.perf_counter() - t0
    assert np.array_equal(back.nodes3d, tree.nodes3d)
    grown = os.path.getsize(path) - os.path.getsize(bare)
    floats = tree.nodes3d.size
    line = (f"| {bpy.app.version_string} | {tree.n_frames}×{tree.n_nodes} ({floats / 1e6:.2f} M floats) | "
            f"+{grown / 1e6:.2f} MB | {1000 * t_store:.0f} ms | {1000 * t_save:.0f} ms ({1000 * t_bare:.0f} without) | "
            f"{1000 * t_open:.0f} ms | "
            f"{1000 * t_load:.0f} ms |")
    report.add("tree kept in the .blend (tests/test_stored_tree.py)",
               ["| Blender | frames×nodes | .blend grows | store | save | open | decode |",
                "|---|---|---|---|---|---|---|", line])
    print("\n" + line)
    assert grown < 1.2 * 4 * floats + 200_000            # float32 and no more: uncompressed .npz, no copies
