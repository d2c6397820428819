"""Levels of detail built in Blender and exported (issue 33): ``<tree>_LOD0``… one mesh each,
branches and leaves joined with two materials, under a ``<tree>_LODGroup`` empty, on one rig (a bone
budget's); lower levels hidden in the view; the triangles Blender counts are the core's; the GLB
carries every level's mesh on one skin; the FBX carries an FBX LOD group node holding the levels in
order (read with a reader written from the FBX binary format, tests/fbx_reader.py)."""
import bpy
import numpy as np
import pytest
from fbx_reader import child, object_name, read_fbx, top
from test_exports import read_glb

from tree_from_video import api
from tree_from_video.core.asset import tree_asset
from tree_from_video.operators.scene import build, export, trees

from trees import empty_scene  # noqa: F401  (autouse fixture)

pytestmark = [pytest.mark.blender]


def _triangles(ob) -> int:
    ob.data.calc_loop_triangles()
    return len(ob.data.loop_triangles)


def test_levels_in_blender_and_in_the_exports(tmp_path):
    tree, = api.generate("broad", node_budget=80, n_frames=12, seed=31)
    built = build.build_tree(bpy.context, tree, "Game", bone_budget=32, lods=3)
    asset = tree_asset(tree, bone_budget=32, lods=3)
    objs = built["lods"]
    assert [ob.name for ob in objs] == ["Game_LOD0", "Game_LOD1", "Game_LOD2"] and built["mesh"] is objs[0]
    assert built["leaves"] is None
    layer = bpy.context.view_layer
    for k, (ob, level) in enumerate(zip(objs, asset.lods)):
        assert _triangles(ob) == level.triangles
        assert [m.name for m in ob.data.materials] == ["Game Bark", "Game Leaf"]
        assert ob.parent.name == "Game_LODGroup" and ob.parent.parent is built["armature"]
        assert ob.hide_get(view_layer=layer) == (k > 0) and ob.hide_render == (k > 0)
        groups = {g.name for g in ob.vertex_groups}
        assert groups <= set(asset.rig.names)
        counts = np.array([len(v.groups) for v in ob.data.vertices])
        assert (counts == 1).all()
    assert objs[0].data.shape_keys is not None and objs[1].data.shape_keys is None     # LOD0's flap only
    objects = trees.tree_objects(built["collection"])
    doc, _ = read_glb(export.export_gltf(tmp_path / "game.glb", objects))
    names = sorted(m["name"] for m in doc["meshes"])
    assert names == ["Game_LOD0", "Game_LOD1", "Game_LOD2"]
    assert len(doc["skins"]) == 1 and len(doc["skins"][0]["joints"]) == len(asset.rig.names)
    # the leaves alpha-tested in the GLB (MASK), and the material as it was once the export is done
    mats = {m["name"]: m for m in doc["materials"]}
    assert mats["Game Leaf"]["alphaMode"] == "MASK" and mats["Game Leaf"].get("alphaCutoff", 0.5) == 0.5
    leaf = bpy.data.materials["Game Leaf"]
    assert not any(n.type == "MATH" for n in leaf.node_tree.nodes)
    assert leaf.node_tree.nodes["Principled BSDF"].inputs["Alpha"].links[0].from_node.type == "TEX_IMAGE"
    fbx = read_fbx(export.export_fbx(tmp_path / "game.fbx", objects))
    objs_node = top(fbx, "Objects")
    groups = [n for n in child(objs_node, "NodeAttribute") if n["props"][2] == b"LodGroup"]
    assert len(groups) == 1
    models = {n["props"][0]: object_name(n["props"][1]) for n in child(objs_node, "Model")}
    group_model = next(i for i, name in models.items() if name == "Game_LODGroup")
    links = [c["props"] for c in child(top(fbx, "Connections"), "C")]
    assert [b"OO", groups[0]["props"][0], group_model] in [list(p[:3]) for p in links]   # the attribute on its node
    kids = [models[p[1]] for p in links if p[0] == b"OO" and p[2] == group_model and p[1] in models]
    assert sorted(kids) == ["Game_LOD0", "Game_LOD1", "Game_LOD2"]
