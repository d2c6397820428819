"""An export carries its own tree's animation and nothing else, whatever else the file holds.

The flow an artist follows: reconstruct a tree, export it, press *Generate* (another tree whose
bones are also named ``B001``…), build a forest, export the reconstruction again. In Blender 4.3
the glTF exporter used to merge every armature action of the file into the exported skin by bone
name (the generated tree's rotations on the reconstruction's bones, its key count). Here every
format's second export must equal the first, and a forest tree's export its own animation."""
import os

import bpy
import numpy as np
import pytest
from test_exports import accessor, read_glb

from tree_from_video.core.errors import InputError
from tree_from_video.operators.scene import export
from tree_from_video.operators.scene.build import build_tree

from trees import (
    binary_tree,
    broad_tree,
    empty_scene,  # noqa: F401  (autouse: a fresh scene per test)
    played,
    pose_heads_dirs,
    tree_height,
)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

RECON_FRAMES = 60


def tree_objects(coll) -> list:
    """What an export of the tree ``coll`` writes: its armature and meshes."""
    return [ob for ob in coll.all_objects if ob.type in ("ARMATURE", "MESH")]


def _crowd(context):
    """A generated-like tree (180 frames, 24 fps, bones B001..B127) and a 2-tree forest beside the
    reconstruction; returns the built generated tree."""
    gen = build_tree(context, binary_tree(127, 180, 24.0, seed=3), "Generated")
    forest = bpy.data.collections.new("Forest")
    context.scene.collection.children.link(forest)
    for k in (4, 5):
        built = build_tree(context, binary_tree(63, 120, 24.0, seed=k), f"Forest Tree {k}")
        context.scene.collection.children.unlink(built["collection"])
        forest.children.link(built["collection"])
    return gen


def _gltf_rotations(path) -> dict:
    doc, binary = read_glb(path)
    assert len(doc["animations"]) == 1
    anim = doc["animations"][0]
    out = {}
    for ch in anim["channels"]:
        if ch["target"]["path"] == "rotation":
            node = doc["nodes"][ch["target"]["node"]]["name"]
            s = anim["samplers"][ch["sampler"]]
            out[node] = (accessor(doc, binary, s["input"]), accessor(doc, binary, s["output"]))
    return out


def test_gltf_after_generate_and_a_forest_is_the_same_animation(tmp_path):
    recon = build_tree(bpy.context, broad_tree(RECON_FRAMES), "Reconstruction")
    objs = tree_objects(recon["collection"])
    first = export.export_gltf(tmp_path / "first.glb", objs)
    gen = _crowd(bpy.context)
    second = export.export_gltf(tmp_path / "second.glb", objs)
    a, b = _gltf_rotations(first), _gltf_rotations(second)
    assert set(a) == set(b) and len(a) == len(recon["armature"].data.bones)
    for name in a:
        ta, ra = a[name]
        tb, rb = b[name]
        assert len(tb) == RECON_FRAMES, name                       # not the generated tree's 180 keys
        np.testing.assert_array_equal(ta, tb)
        np.testing.assert_array_equal(ra, rb)
    # the generated tree exports its own 180 frames, its own bones only
    g = _gltf_rotations(export.export_gltf(tmp_path / "gen.glb", tree_objects(gen["collection"])))
    assert len(g) == len(gen["armature"].data.bones) == 127
    assert all(len(t) == 180 for t, _ in g.values())


def test_fbx_after_generate_keeps_the_reconstructions_motion(tmp_path):
    tree = broad_tree(RECON_FRAMES)
    recon = build_tree(bpy.context, tree, "Reconstruction")
    names = [f"B{c:03d}" for c in tree.edges()[:, 1]]
    want = played(recon["armature"], names, (1, 17, 45, RECON_FRAMES))   # before the crowd arrives
    _crowd(bpy.context)
    path = export.export_fbx(tmp_path / "recon.fbx", tree_objects(recon["collection"]))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.fbx(filepath=path)
    rigs = [ob for ob in bpy.context.scene.objects if ob.type == "ARMATURE"]
    assert len(rigs) == 1 and len(rigs[0].data.bones) == tree.n_nodes - 1
    tol = 1e-4 * tree_height(tree)
    for k in (1, 17, 45, RECON_FRAMES):
        bpy.context.scene.frame_set(k)
        heads, _, dirs = want[k]
        got_heads, got_dirs = pose_heads_dirs(rigs[0], names)
        np.testing.assert_allclose(got_heads, heads, atol=tol)
        np.testing.assert_allclose(got_dirs, dirs, atol=1e-3)


def test_usd_after_generate_is_the_same_animation_or_a_clear_error(tmp_path):
    recon = build_tree(bpy.context, broad_tree(RECON_FRAMES), "Reconstruction")
    objs = tree_objects(recon["collection"])
    if not export.has_usd():
        with pytest.raises(InputError, match="built without USD"):
            export.export_usd(tmp_path / "a.usdc", objs)
        return
    first = export.export_usd(tmp_path / "first.usdc", objs)
    _crowd(bpy.context)
    second = export.export_usd(tmp_path / "second.usdc", objs)
    from pxr import Usd, UsdSkel  # usd-core: in every target whose Blender has USD (requirements)

    def rotations(path):
        stage = Usd.Stage.Open(path)
        anims = [UsdSkel.Animation(p) for p in stage.Traverse() if p.IsA(UsdSkel.Animation)]
        assert len(anims) == 1
        attr = anims[0].GetRotationsAttr()
        times = attr.GetTimeSamples()
        return times, np.array([np.array(attr.Get(t), dtype=float) for t in times])

    ta, ra = rotations(first)
    tb, rb = rotations(second)
    assert list(ta) == list(tb) and len(ta) == RECON_FRAMES
    np.testing.assert_array_equal(ra, rb)


def test_exports_leave_every_trees_action_assigned(tmp_path):
    """Exporting does not unassign or swap anything in the scene."""
    recon = build_tree(bpy.context, broad_tree(RECON_FRAMES), "Reconstruction")
    gen = _crowd(bpy.context)
    before = {ob.name: ob.animation_data.action.name for ob in bpy.data.objects
              if ob.animation_data is not None and ob.animation_data.action is not None}
    export.export_gltf(tmp_path / "r.glb", tree_objects(recon["collection"]))
    export.export_fbx(tmp_path / "g.fbx", tree_objects(gen["collection"]))
    after = {ob.name: ob.animation_data.action.name for ob in bpy.data.objects
             if ob.animation_data is not None and ob.animation_data.action is not None}
    assert before == after and len(before) >= 4
    assert os.path.getsize(tmp_path / "r.glb") > 0


def test_the_artists_flow_through_the_operators(tmp_path):
    """The issue's flow through the buttons: Reconstruct, Export (GLB), Generate Tree, Export the
    reconstruction again — the two files hold the same animation."""
    import tree_from_video as pkg

    from samples import committed
    pkg.register()
    try:
        p = bpy.context.scene.tree_video
        p.video_path = os.path.join(committed("broad"), "video.mp4")
        p.outline_path = os.path.join(committed("broad"), "outline.json")
        p.use_frame_range, p.frame_start, p.frame_end = True, 1, 40
        p.build_leaves, p.twig_depth = False, 0
        assert bpy.ops.tree_video.reconstruct("EXEC_DEFAULT") == {"FINISHED"}
        recon = bpy.data.collections[p.collection_name]
        p.export_scope, p.export_tree, p.export_format = "PICK", recon, "GLB"
        p.output_dir, p.export_name = str(tmp_path), "first"
        assert bpy.ops.tree_video.export("EXEC_DEFAULT") == {"FINISHED"}
        p.species_source, p.envelope_source, p.species_name = "LIBRARY", "CIRCLE", "broad"
        p.gen_frames, p.gen_nodes = 90, 80
        assert bpy.ops.tree_video.generate("EXEC_DEFAULT") == {"FINISHED"}
        p.export_scope, p.export_tree, p.export_name = "PICK", recon, "second"
        assert bpy.ops.tree_video.export("EXEC_DEFAULT") == {"FINISHED"}
        a, b = _gltf_rotations(tmp_path / "first.glb"), _gltf_rotations(tmp_path / "second.glb")
        assert set(a) == set(b) and len(a) > 50
        for name in a:
            assert len(b[name][0]) == 40, name                      # the reconstruction's 40 keys, not 90
            np.testing.assert_array_equal(a[name][1], b[name][1])
    finally:
        pkg.unregister()
