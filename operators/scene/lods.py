"""A tree's levels of detail and collision capsules in Blender, copied from the asset
(:mod:`core.asset.lod`, :mod:`core.asset.collision`): one mesh object per level, ``<tree>_LOD0``,
``<tree>_LOD1``… (Unity builds a LODGroup from these suffixes), each the branch tubes and the leaf
cards joined, two materials (bark, leaf), skinned to the one rig. Levels after the first are hidden
in the viewport and in renders (the exports still write them: an export links its objects into a
scene of its own, where they show). Capsules ``UCP_<tree>_NN`` are wire meshes at rest."""
from __future__ import annotations

import bpy
import numpy as np

from ...core.asset.collision import Capsule, capsule_mesh, capsule_name
from ...core.asset.lod import Lod
from .leaves import add_leaf_flap
from .objects import Created, new_mesh, weight_by_bone


def lod_name(tree: str, level: int) -> str:
    """``"<tree>_LOD<k>"``: the suffix Unity's importer groups by."""
    return f"{tree}_LOD{level}"


def build_lod(lod: Lod, level: int, names: list[str], rig, coll, tree: str, bark, leaf, created: Created):
    """The mesh object of ``lod``: branch polygons (material 0, ``bark``) then leaf quads (material
    1, ``leaf``), one UV map, the leaves' colours in ``"Col"`` (white on the bark), one vertex group
    per bone of ``names`` that carries vertices, an Armature modifier, parented to ``rig``; LOD0's
    leaf flap as shape keys (zero on the bark)."""
    name = lod_name(tree, level)
    b, lv = lod.branches, lod.leaves
    co, loop_vert, totals, uv, smooth, bone, mat_index = [], [], [], [], [], [], []
    nb = 0
    if b is not None:
        nb = len(b.co)
        co.append(b.co)
        loop_vert.append(b.loop_vert)
        totals.append(b.loop_total)
        uv.append(b.uv)
        smooth.append(b.smooth)
        bone.append(b.bone)
        mat_index.append(np.zeros(len(b.loop_total), np.int32))
    if lv is not None:
        V = len(lv.co)
        co.append(lv.co)
        loop_vert.append(nb + np.arange(V, dtype=np.int32))
        totals.append(np.full(lv.quads, 4, np.int32))
        uv.append(lv.uv)
        smooth.append(np.zeros(lv.quads, bool))
        bone.append(lv.bone)
        mat_index.append(np.full(lv.quads, 1 if b is not None else 0, np.int32))
    CO = np.concatenate(co).astype(np.float32)
    me = new_mesh(name, CO, np.concatenate(loop_vert), np.concatenate(totals), created)
    me.polygons.foreach_set("use_smooth", np.concatenate(smooth))
    me.polygons.foreach_set("material_index", np.concatenate(mat_index))
    layer = me.uv_layers.new(name="UVMap")
    layer.data.foreach_set("uv", np.concatenate(uv).astype(np.float32).ravel())
    if lv is not None:
        rgba = np.ones((len(CO), 4), np.float32)
        rgba[nb:, :3] = lv.colour
        me.color_attributes.new("Col", "BYTE_COLOR", "POINT").data.foreach_set("color_srgb", rgba.ravel())
    for mat in ((bark,) if b is not None else ()) + ((leaf,) if lv is not None else ()):
        me.materials.append(mat)
    me.update()
    ob = created.add(bpy.data.objects, bpy.data.objects.new(name, me))
    coll.objects.link(ob)
    weight_by_bone(ob, np.concatenate(bone).astype(np.int64), names)
    mod = ob.modifiers.new("Armature", "ARMATURE")
    mod.object = rig
    ob.parent = rig
    if lv is not None and lv.flap is not None:
        offsets = np.zeros((len(lv.flap.offsets), len(CO), 3), np.float32)
        offsets[:, nb:] = lv.flap.offsets
        flap = type(lv.flap)(offsets, lv.flap.weights, lv.flap.names)
        add_leaf_flap(ob, flap, CO, name, created)
    if level > 0:                       # the artist sees LOD0; every level exports
        ob.hide_render = True
    return ob


def lod_group(rig, coll, tree: str, objs, created: Created):
    """An empty ``"<tree>_LODGroup"`` (child of ``rig``, at its origin) holding the levels: the FBX
    exporter writes an empty whose ``fbx_type`` property is ``"LodGroup"`` as an FBX LOD group node
    (Blender's ``io_scene_fbx`` ``fbx_data_empty_elements``), the node Unreal's "Import Mesh LODs"
    reads (``FFbxImporter::FindAllLODGroupNode``); Unity groups the children by their ``_LOD<k>``
    suffix."""
    empty = created.add(bpy.data.objects, bpy.data.objects.new(f"{tree}_LODGroup", None))
    empty["fbx_type"] = "LodGroup"
    coll.objects.link(empty)
    empty.parent = rig
    for ob in objs:
        ob.parent = empty
    return empty


def hide_lower_levels(context, objs) -> None:
    """Hide every level after the first in the current view layer (not ``hide_viewport``, which
    would keep the exporters' "selected only" from selecting them in their own scene)."""
    for ob in objs[1:]:
        try:
            ob.hide_set(True, view_layer=context.view_layer)
        except RuntimeError:
            pass


#: the custom property marking a collision capsule (FBX writes it; glTF and USD leave it out)
COLLISION_KEY = "tree_video_collision"


def build_capsule(c: Capsule, k: int, rig, coll, tree: str, created: Created):
    """The capsule mesh ``UCP_<tree>_NN`` (Unreal fits a capsule to it on import), child of ``rig``
    at rest, drawn as wire and not rendered."""
    name = capsule_name(tree, k)
    me = new_mesh(name, *capsule_mesh(c), created)
    ob = created.add(bpy.data.objects, bpy.data.objects.new(name, me))
    ob[COLLISION_KEY] = True
    coll.objects.link(ob)
    ob.parent = rig
    ob.display_type = "WIRE"
    ob.hide_render = True
    return ob
