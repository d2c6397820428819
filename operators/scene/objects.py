"""Objects and data-blocks of a built tree: what a build has created so far (removed newest first
when it fails), removing a tree's collection with the data only it used, a free collection name,
deselecting, and reading an object's evaluated mesh in world space."""
from __future__ import annotations

import bpy
import numpy as np

from .materials import material_images


class Created:
    """Data-blocks made so far, removed newest first on failure."""

    def __init__(self):
        self.items: list[tuple] = []
        self.undo: list = []

    def add(self, collection, id_):
        self.items.append((collection, id_))
        return id_

    def on_failure(self, undo) -> None:
        """Call ``undo()`` (e.g. restore scene settings) when the build fails."""
        self.undo.append(undo)

    def remove(self, context) -> None:
        for undo in reversed(self.undo):
            try:
                undo()
            except (ReferenceError, RuntimeError, TypeError, ValueError):
                pass
        for _, id_ in self.items:
            try:
                if isinstance(id_, bpy.types.Object) and id_.mode != "OBJECT":
                    with context.temp_override(active_object=id_, object=id_):
                        bpy.ops.object.mode_set(mode="OBJECT")
            except (ReferenceError, RuntimeError):
                pass
        for collection, id_ in reversed(self.items):
            try:
                collection.remove(id_)
            except ReferenceError:                  # already gone with its owner
                pass
        self.items.clear()
        self.undo.clear()


def _data_collection(id_):
    for attr, typ in (("meshes", bpy.types.Mesh), ("armatures", bpy.types.Armature),
                      ("actions", bpy.types.Action), ("materials", bpy.types.Material),
                      ("curves", bpy.types.Curve), ("images", bpy.types.Image)):
        if isinstance(id_, typ):
            return getattr(bpy.data, attr)
    raise TypeError(f"no removal for {type(id_).__name__}")


def remove_collection(coll: bpy.types.Collection) -> None:
    """Remove ``coll``, its child collections, all their objects, and the objects' data, actions and
    materials that nothing else uses any more."""
    objects = set(coll.all_objects)
    datas, actions, materials = set(), set(), set()
    for ob in objects:
        if ob.data is not None:
            datas.add(ob.data)
            materials.update(m for m in getattr(ob.data, "materials", ()) if m is not None)
        for owner in (ob, getattr(ob.data, "shape_keys", None)):     # the leaves' flap keys too
            ad = getattr(owner, "animation_data", None)
            if ad is not None and ad.action is not None:
                actions.add(ad.action)
    children = list(coll.children_recursive)
    for ob in objects:
        bpy.data.objects.remove(ob, do_unlink=True)
    images = {img for m in materials for img in material_images(m)}
    for ids in (datas, actions, materials, images):
        for id_ in ids:
            if id_.users == 0:
                _data_collection(id_).remove(id_)
    for c in reversed(children):
        if not c.all_objects:
            bpy.data.collections.remove(c)
    bpy.data.collections.remove(coll)


def deselect_all(view_layer) -> None:
    """Deselect every object of ``view_layer`` (skipping entries of objects just removed, which
    read as None until the view layer resyncs)."""
    for ob in view_layer.objects:
        if ob is not None and ob.select_get():
            ob.select_set(False)


def evaluated_world_mesh(ob, triangles: bool = False):
    """World-space vertices ``(V, 3)`` float64 of ``ob``'s evaluated mesh (modifiers, armature
    pose; curves too), and with ``triangles`` its loop triangles ``(T, 3)`` vertex indices (else
    None)."""
    dg = bpy.context.evaluated_depsgraph_get()
    ev = ob.evaluated_get(dg)
    me = ev.to_mesh()
    try:
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        tri = None
        if triangles:
            me.calc_loop_triangles()
            tri = np.empty(len(me.loop_triangles) * 3, np.int32)
            me.loop_triangles.foreach_get("vertices", tri)
            tri = tri.reshape(-1, 3)
    finally:
        ev.to_mesh_clear()
    mw = np.array(ev.matrix_world)
    return co.reshape(-1, 3).astype(np.float64) @ mw[:3, :3].T + mw[:3, 3], tri


def unique_collection_name(base: str) -> str:
    """``base``, or ``base.001``, ``base.002``… : the first name no collection has yet."""
    name, k = base, 1
    while bpy.data.collections.get(name) is not None:
        name = f"{base}.{k:03d}"
        k += 1
    return name


def new_mesh(name: str, co: np.ndarray, loop_vert: np.ndarray, loop_total: np.ndarray, created: Created):
    """A mesh ``name`` of vertices ``co (V, 3)`` metres and polygons given as their corners
    ``loop_vert (L,)`` in order, ``loop_total (P,)`` corners each, bulk-filled by ``foreach_set``,
    its edges computed; ``created`` collects it for rollback."""
    totals = np.asarray(loop_total, np.int32)
    me = created.add(bpy.data.meshes, bpy.data.meshes.new(name))
    me.vertices.add(len(co))
    me.vertices.foreach_set("co", np.asarray(co, np.float32).ravel())
    me.loops.add(len(loop_vert))
    me.loops.foreach_set("vertex_index", np.asarray(loop_vert, np.int32))
    me.polygons.add(len(totals))
    me.polygons.foreach_set("loop_start", np.concatenate([[0], np.cumsum(totals)[:-1]]).astype(np.int32))
    me.polygons.foreach_set("loop_total", totals)
    me.update(calc_edges=True)
    return me


def add_vertex_uv(ob, name: str, uv: np.ndarray) -> None:
    """A UV map ``name`` on ``ob``'s mesh holding ``uv (V, 2)`` per vertex (every loop of a vertex
    the same), appended after the existing ones (the second map is glTF's TEXCOORD_1, FBX's UV
    set 1)."""
    me = ob.data
    lv = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", lv)
    layer = me.uv_layers.new(name=name, do_init=False)
    layer.data.foreach_set("uv", np.asarray(uv, np.float32)[lv].ravel())


def weight_by_bone(ob, bone: np.ndarray, names: list[str]) -> None:
    """A vertex group for each bone of ``names`` that carries vertices (``bone (V,)`` indices into
    ``names``) holding them with weight 1 (vertex weights have no foreach_set: one call per group)."""
    order = np.argsort(bone, kind="stable")
    used, first, count = np.unique(bone[order], return_index=True, return_counts=True)
    for b, start, n in zip(used, first, count):
        ob.vertex_groups.new(name=names[b]).add(order[start:start + n].tolist(), 1.0, "REPLACE")
