"""Build an animated :class:`Tree3D` in the scene: a keyed armature, a skinned branch mesh and a
bark material, in a collection of their own.

:func:`build_tree` is all-or-nothing: if any step fails, every object and data-block it created
is removed and the error re-raised. Frame ``t`` of the tree (0-based) is scene frame ``t + 1``.
"""
from __future__ import annotations

import math
import time

import bpy
import numpy as np

from ...core import bones
from ...core.detail import branch_mesh as bm
from ...core.detail.branch_mesh import branch_radii, tube_arrays
from ...core.errors import InputError
from ...core.tree3d import Tree3D
from . import action_api
from . import leaves as leaf_build          # build_tree has a parameter "leaves"

#: Blender's longest ID name (bytes).
MAX_NAME = 63


def build_tree(context, tree: Tree3D, collection_name: str, *, replace: bool = False,
               mesh: bool = True, sides: int = 8, leaves: bool = True,
               leaf_image: str | None = None, curliness: float | None = None,
               bark: str | None = None, materials: dict | None = None, update_frame: bool = True) -> dict:
    """Create the animated tree in a new collection ``collection_name`` under the scene collection.

    Creates an armature object ``"<name> Rig"`` (one bone per edge, ``"B{child:03d}"``, rest pose =
    tree frame 0, roll 0, connected to the parent bone) whose pose bones are keyed in QUATERNION
    mode at every scene frame ``1..F`` (LINEAR keys, action ``"<name> Sway"``); sets the scene's
    fps (``fps`` int + ``fps_base``) and frame range ``1..F``; with ``mesh``, a branch mesh
    ``"<name> Branches"`` (tapered tubes with ``sides`` sides, one vertex group per bone, Armature
    modifier, parented to the rig; ``curliness`` 0..1 and ``bark`` "none"/"smooth"/"rough" as in
    :mod:`core.branch_mesh`, None: from ``tree.meta["mesh"]``, see :func:`mesh_params`) and a bark
    material ``"<name> Bark"``; with ``leaves`` and
    ``tree.leaves``, one bone per leaf cluster (``"L0000"``…, child of its branch bone, keyed with
    its flutter) and a skinned leaf mesh ``"<name> Leaves"`` with material ``"<name> Leaf"``
    (the leaf image ``leaf_image``, packed, or a procedural leaf).

    An existing collection of that name raises :class:`InputError` unless ``replace``; then its
    objects and their data are removed once the new tree is complete (a failed build leaves the
    old tree as it was).

    ``materials`` ``{"bark": Material, "leaf": Material}`` reuses existing materials (a forest
    shares one bark and one leaf material) instead of creating them. ``update_frame=False`` skips
    evaluating the scene at its first frame at the end (a forest does it once after all trees).

    Returns ``{"collection", "armature", "mesh" (or None), "action", "material" (or None),
    "leaves" (or None), "leaf_polygons", "timings"}`` with ``timings`` in seconds (``rotations``,
    ``keys``, ``armature``, ``mesh``, ``leaves``, ``total``)."""
    t_total = time.perf_counter()
    _validate(tree, collection_name, sides)
    branch_params = mesh_params(tree, sides, curliness, bark)
    bm.check_params(branch_params)
    old = bpy.data.collections.get(collection_name)
    if old is not None and not replace:
        raise InputError(f"a collection named '{collection_name}' already exists; choose another name "
                         "or replace it (replace=True)")
    names = {"rig": f"{collection_name} Rig", "action": f"{collection_name} Sway",
             "mesh": f"{collection_name} Branches", "material": f"{collection_name} Bark",
             "leaves": f"{collection_name} Leaves", "leaf_material": f"{collection_name} Leaf"}
    with_leaves = leaves and tree.leaves is not None and tree.leaves.count > 0
    created = _Created()
    timings = {}
    try:
        scene = context.scene
        if context.mode != "OBJECT" and context.active_object is not None:
            bpy.ops.object.mode_set(mode="OBJECT")
        coll = created.add(bpy.data.collections, bpy.data.collections.new(collection_name))
        scene.collection.children.link(coll)

        t = time.perf_counter()
        rig, rest, leaf_names = _build_armature(
            context, tree, coll, names["rig"], created,
            (lambda data: leaf_build.add_leaf_edit_bones(data, tree)) if with_leaves else None)
        timings["armature"] = time.perf_counter() - t

        t = time.perf_counter()
        local = bones.local_rotations(tree.parents, tree.nodes3d, rest)
        timings["rotations"] = time.perf_counter() - t
        t = time.perf_counter()
        action, make_fcurve = _key_pose(rig, local, bones.bone_names(tree.parents), names["action"], created)
        if leaf_names:
            leaf_build.key_leaf_bones(rig, make_fcurve, tree, leaf_names)
        timings["keys"] = time.perf_counter() - t
        render = scene.render
        saved = (render.fps, render.fps_base, scene.frame_start, scene.frame_end, scene.frame_current)
        created.on_failure(lambda: _restore_scene_timing(scene, *saved))
        _set_scene_timing(scene, tree.fps, tree.n_frames)

        mesh_obj = material = None
        if mesh:
            t = time.perf_counter()
            material = (materials or {}).get("bark")
            if material is None:
                material = created.add(bpy.data.materials, bark_material(names["material"], branch_params.bark))
            mesh_obj = _build_mesh(tree, rest, rig, coll, names["mesh"], material, branch_params, created)
            timings["mesh"] = time.perf_counter() - t
        leaf_obj = leaf_mat = None
        if leaf_names:
            t = time.perf_counter()
            leaf_mat = (materials or {}).get("leaf")
            if leaf_mat is None:
                leaf_mat = created.add(bpy.data.materials, leaf_build.leaf_material(
                    names["leaf_material"], leaf_image, leaf_build.leaf_tint(tree.leaves)))
                for img in leaf_build.material_images(leaf_mat):
                    created.add(bpy.data.images, img)
            leaf_obj = leaf_build.build_leaf_mesh(tree, rig, coll, names["leaves"], leaf_names, leaf_mat, created)
            timings["leaves"] = time.perf_counter() - t

        if old is not None:
            remove_collection(old)
            for id_, name in ((coll, collection_name), (rig, names["rig"]), (rig.data, names["rig"]),
                              (action, names["action"]), (mesh_obj, names["mesh"]),
                              (mesh_obj and mesh_obj.data, names["mesh"]), (material, names["material"]),
                              (leaf_obj, names["leaves"]), (leaf_obj and leaf_obj.data, names["leaves"]),
                              (leaf_mat, names["leaf_material"])):
                shared = materials is not None and any(id_ is m for m in materials.values())
                if id_ is not None and id_.name != name and not shared:
                    id_.name = name
        deselect_all(context.view_layer)
        for ob in coll.objects:
            ob.select_set(True)
        context.view_layer.objects.active = rig
        if update_frame:
            scene.frame_set(scene.frame_start)
    except BaseException:
        created.remove(context)
        raise
    timings["total"] = time.perf_counter() - t_total
    return {"collection": coll, "armature": rig, "mesh": mesh_obj, "action": action,
            "material": material, "leaves": leaf_obj,
            "leaf_polygons": tree.leaves.polygons if leaf_obj is not None else 0, "timings": timings}


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
    images = {img for m in materials for img in leaf_build.material_images(m)}
    for ids in (datas, actions, materials, images):
        for id_ in ids:
            if id_.users == 0:
                _data_collection(id_).remove(id_)
    for c in reversed(children):
        if not c.all_objects:
            bpy.data.collections.remove(c)
    bpy.data.collections.remove(coll)


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


def deselect_all(view_layer) -> None:
    """Deselect every object of ``view_layer`` (skipping entries of objects just removed, which
    read as None until the view layer resyncs)."""
    for ob in view_layer.objects:
        if ob is not None and ob.select_get():
            ob.select_set(False)


# ----------------------------------------------------------------------------- validation

def _validate(tree: Tree3D, collection_name: str, sides: int) -> None:
    if not collection_name or len(collection_name.encode()) > MAX_NAME - len(" Branches"):
        raise InputError(f"collection name '{collection_name}' must have 1 to {MAX_NAME - 9} characters")
    if not isinstance(sides, (int, np.integer)) or sides < 3:
        raise InputError(f"tubes need at least 3 sides (got {sides})")
    fps = float(tree.fps)
    if not (math.isfinite(fps) and 0.01 <= fps <= 1000):
        raise InputError(f"the tree's frame rate {tree.fps} is not usable; it must be between 0.01 and 1000 fps")
    radius = np.asarray(tree.radius, np.float64)
    if radius.shape != (tree.n_nodes,) or not np.isfinite(radius).all() or (radius < 0).any():
        raise InputError("the tree's radii must be one finite, non-negative value per node; rebuild the 3D tree")
    bones.check_positions(tree.parents, tree.nodes3d)        # shapes, finite positions, no zero-length bone


# ----------------------------------------------------------------------------- rollback

class _Created:
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


# ----------------------------------------------------------------------------- armature

def _build_armature(context, tree: Tree3D, coll, name: str, created: _Created, extra_edit=None):
    """Armature object with one connected bone per edge at frame-0 positions; ``extra_edit(data)``
    adds more bones in the same edit-mode session (each mode switch updates the whole view layer,
    which is what made forests slow).

    Returns ``(object, rest (B, 3, 3))``: rest rotations read back from ``bone.matrix_local`` in
    :func:`bones.bone_edges` order."""
    edges = bones.bone_edges(tree.parents)
    names = bones.bone_names(tree.parents)
    parent_bone = bones.bone_parents(tree.parents)
    rest_pos = np.asarray(tree.nodes3d[0], np.float32)
    data = created.add(bpy.data.armatures, bpy.data.armatures.new(name))
    data.display_type = "STICK"
    rig = created.add(bpy.data.objects, bpy.data.objects.new(name, data))
    coll.objects.link(rig)
    view_layer = context.view_layer
    deselect_all(view_layer)
    rig.select_set(True)
    view_layer.objects.active = rig
    with context.temp_override(active_object=rig, object=rig, edit_object=rig):   # also in a scratch scene
        bpy.ops.object.mode_set(mode="EDIT")
        try:
            _edit_bones(data, names, rest_pos[edges[:, 0]], rest_pos[edges[:, 1]], parent_bone)
            extra = extra_edit(data) if extra_edit is not None else []
        finally:
            bpy.ops.object.mode_set(mode="OBJECT")

    order = {b.name: i for i, b in enumerate(data.bones)}
    if len(order) != len(names) + len(extra):
        raise RuntimeError(f"the armature has {len(order)} bones, expected {len(names) + len(extra)}")
    flat = np.empty(len(order) * 16, np.float32)
    data.bones.foreach_get("matrix_local", flat)
    mats = flat.reshape(-1, 4, 4).transpose(0, 2, 1)         # foreach_get is column-major
    rest = mats[[order[n] for n in names], :3, :3].astype(np.float64)

    quaternion = bpy.types.PoseBone.bl_rna.properties["rotation_mode"].enum_items["QUATERNION"].value
    rig.pose.bones.foreach_set("rotation_mode", np.full(len(order), quaternion, np.int32))
    return rig, rest, extra


def _edit_bones(data, names: list[str], heads: np.ndarray, tails: np.ndarray, parent_bone: np.ndarray) -> None:
    """In edit mode: bones ``names`` from ``heads``/``tails (B, 3)`` metres, roll 0, each connected
    to ``parent_bone`` (-1: none): its head is the parent's tail, the node they share."""
    ebones = data.edit_bones
    new = [ebones.new(n) for n in names]
    ebones.foreach_set("head", np.asarray(heads, np.float32).ravel())
    ebones.foreach_set("tail", np.asarray(tails, np.float32).ravel())
    ebones.foreach_set("roll", np.zeros(len(names), np.float32))
    for eb, pb in zip(new, parent_bone):
        if pb >= 0:
            eb.parent = new[pb]
            eb.use_connect = True


def _key_pose(rig, local: np.ndarray, names: list[str], action_name: str, created: _Created):
    """Key ``local (F, B, 4)`` quaternions on the rig's pose bones at frames ``1..F``."""
    action, make_fcurve = action_api.new_action(rig, action_name)
    created.add(bpy.data.actions, action)
    frames = np.arange(1, len(local) + 1, dtype=np.float32)
    pose_index = {pb.name: i for i, pb in enumerate(rig.pose.bones)}
    for b, name in enumerate(names):
        if name not in pose_index:
            raise RuntimeError(f"pose bone {name} is missing")
        path = f'pose.bones["{bpy.utils.escape_identifier(name)}"].rotation_quaternion'
        for i in range(4):
            action_api.write_keys(make_fcurve(path, i, name), frames, local[:, b, i])
    return action, make_fcurve


def _set_scene_timing(scene, fps: float, n_frames: int) -> None:
    """Scene frame rate ``fps`` (int ``render.fps`` + ``fps_base`` for fractional rates, e.g.
    29.97 → 30 / 1.001) and frame range ``1..n_frames``."""
    whole = round(fps)
    if abs(whole - fps) < 1e-6 * fps and whole >= 1:
        scene.render.fps, scene.render.fps_base = int(whole), 1.0
    else:
        up = max(1, math.ceil(fps))
        scene.render.fps, scene.render.fps_base = up, up / fps
    set_frame_range(scene, 1, n_frames)


def _restore_scene_timing(scene, fps, fps_base, start, end, current) -> None:
    scene.render.fps, scene.render.fps_base = fps, fps_base
    set_frame_range(scene, start, end)
    scene.frame_current = current


def set_frame_range(scene, start: int, end: int) -> None:
    """Set the scene's frame range. Blender keeps start <= end on every assignment, so assign in
    an order that never crosses the current range."""
    if start > scene.frame_end:
        scene.frame_end, scene.frame_start = end, start
    else:
        scene.frame_start, scene.frame_end = start, end


# ----------------------------------------------------------------------------- mesh

def mesh_params(tree: Tree3D, sides: int = 8, curliness: float | None = None, bark: str | None = None,
                seed: int | None = None) -> bm.MeshParams:
    """The branch mesh settings: the given ones, else those recorded in ``tree.meta["mesh"]``
    (``curliness``, ``bark``, ``seed``; written by ``pipeline.build_3d``), else straight plain tubes."""
    rec = tree.meta.get("mesh") or {}
    return bm.MeshParams(sides=sides,
                         curliness=float(rec.get("curliness", 0.0) if curliness is None else curliness),
                         bark=str(rec.get("bark", "none") if bark is None else bark),
                         seed=int(rec.get("seed", 0) if seed is None else seed))


def _build_mesh(tree: Tree3D, rest: np.ndarray, rig, coll, name: str, material, params: bm.MeshParams,
                created: _Created):
    """The skinned branch mesh object (see :func:`core.branch_mesh.tube_arrays`), parented to
    ``rig``: one vertex group per bone holding its rings (weight 1), bulk-filled by ``foreach_set``."""
    r_head, r_tail = branch_radii(tree.parents, tree.radius)
    floor = 1e-4 * max(float(np.ptp(tree.nodes3d[0], axis=0).max()), 1e-3)
    g = tube_arrays(tree.nodes3d[0], tree.parents, rest, np.maximum(r_head, floor),
                    np.maximum(r_tail, floor), params.sides, curliness=params.curliness, bark=params.bark,
                    rings=params.rings, seed=params.seed)
    me = created.add(bpy.data.meshes, bpy.data.meshes.new(name))
    me.vertices.add(len(g["co"]))
    me.vertices.foreach_set("co", g["co"].astype(np.float32).ravel())
    me.loops.add(len(g["loop_vert"]))
    me.loops.foreach_set("vertex_index", g["loop_vert"].astype(np.int32))
    me.polygons.add(len(g["loop_start"]))
    me.polygons.foreach_set("loop_start", g["loop_start"].astype(np.int32))
    me.polygons.foreach_set("loop_total", g["loop_total"].astype(np.int32))
    me.update(calc_edges=True)
    me.polygons.foreach_set("use_smooth", g["smooth"])
    uv = me.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", g["uv"].astype(np.float32).ravel())
    me.materials.append(material)
    me.update()

    ob = created.add(bpy.data.objects, bpy.data.objects.new(name, me))
    coll.objects.link(ob)
    bone_names = bones.bone_names(tree.parents)
    per_bone = g["rings"] * g["sides"]
    for b, bname in enumerate(bone_names):         # one call per bone (vertex weights have no foreach_set)
        ob.vertex_groups.new(name=bname).add(list(range(b * per_bone, (b + 1) * per_bone)), 1.0, "REPLACE")
    mod = ob.modifiers.new("Armature", "ARMATURE")
    mod.object = rig
    ob.parent = rig
    return ob


#: bark material by preset: (bump strength, furrow share of the relief)
BARK_LOOK = {"none": (0.35, 0.0), "smooth": (0.2, 0.15), "rough": (0.6, 0.6)}


def principled_nodes(mat):
    """``mat``'s node tree emptied (nodes switched on first on Blender 4.x; 5.x always has them),
    with a Material Output and a Principled BSDF: ``(node_tree, output, bsdf)``."""
    if mat.node_tree is None:
        mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    return nt, nt.nodes.new("ShaderNodeOutputMaterial"), nt.nodes.new("ShaderNodeBsdfPrincipled")


def bark_material(name: str, kind: str = "none") -> bpy.types.Material:
    """A Principled BSDF bark, procedural and UV-mapped (the bark follows the bending branches):
    brown-grey noise colour; bump from Voronoi cells plus, for ``kind`` "smooth"/"rough", furrows
    along the branch (a distorted Wave texture in bands across u, i.e. running along v), with the
    strengths of :data:`BARK_LOOK`. The caller removes it on failure."""
    strength, furrow = BARK_LOOK.get(kind, BARK_LOOK["none"])
    mat = bpy.data.materials.new(name)
    try:
        mat.diffuse_color = (0.22, 0.17, 0.13, 1.0)          # solid-view colour
        mat.roughness = 0.9
        nt, out, bsdf = principled_nodes(mat)
        coord = nt.nodes.new("ShaderNodeTexCoord")
        mapping = nt.nodes.new("ShaderNodeMapping")
        noise = nt.nodes.new("ShaderNodeTexNoise")
        voronoi = nt.nodes.new("ShaderNodeTexVoronoi")
        ramp = nt.nodes.new("ShaderNodeValToRGB")
        bump = nt.nodes.new("ShaderNodeBump")
        for i, node in enumerate((coord, mapping, noise, voronoi, ramp, bump, bsdf, out)):
            node.location = (220 * i - 900, 150 * ((i % 2) * 2 - 1))
        mapping.inputs["Scale"].default_value = (4.0, 6.0, 4.0)
        noise.inputs["Scale"].default_value = 3.0
        noise.inputs["Detail"].default_value = 8.0
        voronoi.inputs["Scale"].default_value = 5.0
        ramp.color_ramp.elements[0].color = (0.07, 0.055, 0.045, 1.0)
        ramp.color_ramp.elements[1].color = (0.33, 0.29, 0.25, 1.0)
        bump.inputs["Strength"].default_value = strength
        bsdf.inputs["Roughness"].default_value = 0.9
        link = nt.links.new
        link(coord.outputs["UV"], mapping.inputs["Vector"])
        link(mapping.outputs["Vector"], noise.inputs["Vector"])
        link(mapping.outputs["Vector"], voronoi.inputs["Vector"])
        link(noise.outputs["Fac"], ramp.inputs["Fac"])
        link(ramp.outputs["Color"], bsdf.inputs["Base Color"])
        height = voronoi.outputs["Distance"]
        if furrow > 0:
            wave = nt.nodes.new("ShaderNodeTexWave")
            wave.wave_type = "BANDS"
            wave.bands_direction = "X"                       # bands across u: furrows along the branch
            wave.inputs["Scale"].default_value = 2.0
            wave.inputs["Distortion"].default_value = 6.0
            wave.inputs["Detail"].default_value = 4.0
            mix = nt.nodes.new("ShaderNodeMath")
            mix.operation = "MULTIPLY_ADD"                   # wave · furrow + Voronoi distance
            mix.inputs[1].default_value = furrow
            wave.location, mix.location = (-460, -350), (-240, -350)
            link(mapping.outputs["Vector"], wave.inputs["Vector"])
            link(wave.outputs["Fac"], mix.inputs[0])
            link(voronoi.outputs["Distance"], mix.inputs[2])
            height = mix.outputs["Value"]
        link(height, bump.inputs["Height"])
        link(bump.outputs["Normal"], bsdf.inputs["Normal"])
        link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    except BaseException:
        bpy.data.materials.remove(mat)
        raise
    return mat
