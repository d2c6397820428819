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

from ..core import bones as bn
from ..core.errors import InputError
from ..core.tree3d import Tree3D
from . import action_api

#: Blender's longest ID name (bytes).
MAX_NAME = 63


def build_tree(context, tree: Tree3D, collection_name: str, *, replace: bool = False,
               mesh: bool = True, sides: int = 8) -> dict:
    """Create the animated tree in a new collection ``collection_name`` under the scene collection.

    Creates an armature object ``"<name> Rig"`` (one bone per edge, ``"B{child:03d}"``, rest pose =
    tree frame 0, roll 0, connected to the parent bone) whose pose bones are keyed in QUATERNION
    mode at every scene frame ``1..F`` (LINEAR keys, action ``"<name> Sway"``); sets the scene's
    fps (``fps`` int + ``fps_base``) and frame range ``1..F``; with ``mesh``, a branch mesh
    ``"<name> Branches"`` (tapered tubes with ``sides`` sides, one vertex group per bone, Armature
    modifier, parented to the rig) and a bark material ``"<name> Bark"``.

    An existing collection of that name raises :class:`InputError` unless ``replace``; then its
    objects and their data are removed once the new tree is complete (a failed build leaves the
    old tree as it was).

    Returns ``{"collection", "armature", "mesh" (or None), "action", "material" (or None),
    "timings"}`` with ``timings`` in seconds (``rotations``, ``keys``, ``armature``, ``mesh``,
    ``total``)."""
    t_total = time.perf_counter()
    _validate(tree, collection_name, sides)
    old = bpy.data.collections.get(collection_name)
    if old is not None and not replace:
        raise InputError(f"a collection named '{collection_name}' already exists; choose another name "
                         "or replace it (replace=True)")
    names = {"rig": f"{collection_name} Rig", "action": f"{collection_name} Sway",
             "mesh": f"{collection_name} Branches", "material": f"{collection_name} Bark"}
    created = _Created()
    timings = {}
    try:
        scene = context.scene
        if context.mode != "OBJECT" and context.active_object is not None:
            bpy.ops.object.mode_set(mode="OBJECT")
        coll = created.add(bpy.data.collections, bpy.data.collections.new(collection_name))
        scene.collection.children.link(coll)

        t = time.perf_counter()
        rig, rest = _build_armature(context, tree, coll, names["rig"], created)
        timings["armature"] = time.perf_counter() - t

        t = time.perf_counter()
        local = bn.local_rotations(tree.parents, tree.nodes3d, rest)
        timings["rotations"] = time.perf_counter() - t
        t = time.perf_counter()
        action = _key_pose(rig, local, bn.bone_names(tree.parents), names["action"], created)
        timings["keys"] = time.perf_counter() - t
        render = scene.render
        saved = (render.fps, render.fps_base, scene.frame_start, scene.frame_end, scene.frame_current)
        created.on_failure(lambda: _restore_scene_timing(scene, *saved))
        _set_scene_timing(scene, tree.fps, tree.n_frames)

        mesh_obj = material = None
        if mesh:
            t = time.perf_counter()
            material = created.add(bpy.data.materials, bark_material(names["material"]))
            mesh_obj = _build_mesh(tree, rest, rig, coll, names["mesh"], material, sides, created)
            timings["mesh"] = time.perf_counter() - t

        if old is not None:
            remove_collection(old)
            for id_, name in ((coll, collection_name), (rig, names["rig"]), (rig.data, names["rig"]),
                              (action, names["action"]), (mesh_obj, names["mesh"]),
                              (mesh_obj and mesh_obj.data, names["mesh"]), (material, names["material"])):
                if id_ is not None and id_.name != name:
                    id_.name = name
        deselect_all(context.view_layer)
        for ob in coll.objects:
            ob.select_set(True)
        context.view_layer.objects.active = rig
        scene.frame_set(scene.frame_start)
    except BaseException:
        created.remove(context)
        raise
    timings["total"] = time.perf_counter() - t_total
    return {"collection": coll, "armature": rig, "mesh": mesh_obj, "action": action,
            "material": material, "timings": timings}


def remove_collection(coll: bpy.types.Collection) -> None:
    """Remove ``coll``, its child collections, all their objects, and the objects' data, actions and
    materials that nothing else uses any more."""
    objects = set(coll.all_objects)
    datas, actions, materials = set(), set(), set()
    for ob in objects:
        if ob.data is not None:
            datas.add(ob.data)
            materials.update(m for m in getattr(ob.data, "materials", ()) if m is not None)
        if ob.animation_data is not None and ob.animation_data.action is not None:
            actions.add(ob.animation_data.action)
    children = list(coll.children_recursive)
    for ob in objects:
        bpy.data.objects.remove(ob, do_unlink=True)
    for ids in (datas, actions, materials):
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
    bn.check_positions(tree.parents, tree.nodes3d)        # shapes, finite positions, no zero-length bone


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
                      ("curves", bpy.types.Curve)):
        if isinstance(id_, typ):
            return getattr(bpy.data, attr)
    raise TypeError(f"no removal for {type(id_).__name__}")


# ----------------------------------------------------------------------------- armature

def _build_armature(context, tree: Tree3D, coll, name: str, created: _Created):
    """Armature object with one connected bone per edge at frame-0 positions.

    Returns ``(object, rest (B, 3, 3))``: rest rotations read back from ``bone.matrix_local`` in
    :func:`bones.bone_edges` order."""
    edges = bn.bone_edges(tree.parents)
    names = bn.bone_names(tree.parents)
    parent_bone = bn.bone_parents(tree.parents)
    rest_pos = np.asarray(tree.nodes3d[0], np.float32)
    data = created.add(bpy.data.armatures, bpy.data.armatures.new(name))
    data.display_type = "STICK"
    rig = created.add(bpy.data.objects, bpy.data.objects.new(name, data))
    coll.objects.link(rig)
    view_layer = context.view_layer
    deselect_all(view_layer)
    rig.select_set(True)
    view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    _edit_bones(data, names, rest_pos[edges[:, 0]], rest_pos[edges[:, 1]], parent_bone)
    bpy.ops.object.mode_set(mode="OBJECT")

    order = {b.name: i for i, b in enumerate(data.bones)}
    if len(order) != len(names):
        raise RuntimeError(f"the armature has {len(order)} bones, expected {len(names)}")
    flat = np.empty(len(order) * 16, np.float32)
    data.bones.foreach_get("matrix_local", flat)
    mats = flat.reshape(-1, 4, 4).transpose(0, 2, 1)         # foreach_get is column-major
    rest = mats[[order[n] for n in names], :3, :3].astype(np.float64)

    quaternion = bpy.types.PoseBone.bl_rna.properties["rotation_mode"].enum_items["QUATERNION"].value
    rig.pose.bones.foreach_set("rotation_mode", np.full(len(names), quaternion, np.int32))
    return rig, rest


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
    return action


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

def branch_radii(parents: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tube radii at each bone's head and tail, ``(B,)`` each, metres.

    The tail takes its node's radius. The head takes the parent node's radius if the bone
    continues its parent branch (it is the thickest child), else the smaller of the two: a side
    branch starts as thick as itself, not as the trunk it leaves."""
    edges = bn.bone_edges(parents)
    radius = np.asarray(radius, np.float64)
    r_tail = radius[edges[:, 1]]
    thickest = np.zeros(len(parents))
    np.maximum.at(thickest, edges[:, 0], r_tail)
    main = r_tail >= thickest[edges[:, 0]]
    r_head = np.where(main, radius[edges[:, 0]], np.minimum(radius[edges[:, 0]], r_tail))
    return r_head, r_tail


def tube_arrays(rest_pos: np.ndarray, parents: np.ndarray, rest: np.ndarray, r_head: np.ndarray,
                r_tail: np.ndarray, sides: int = 8) -> dict:
    """Geometry of one closed tapered tube per bone (pure numpy).

    ``rest_pos (N, 3)`` metres, ``rest (B, 3, 3)`` bone rest rotations (rings lie in the bones'
    X/Z planes), radii ``(B,)`` metres. Each tube of a bone with a parent bone starts ``r_head``
    (at most half the parent's length) before its head, inside the parent's tube, so joints stay
    closed when the tree bends; both ends are capped.

    Returns arrays: ``co (V, 3)``; ``loop_vert (L,)``; ``loop_start``, ``loop_total``,
    ``smooth (P,)``; ``uv (L, 2)`` (u around in [0, 1], v along the branch from the trunk base in
    metres ÷ the thickest tube's circumference, so bark texels are square on the trunk);
    ``vert_bone (V,)``. ``V = 2·S·B``, ``P = (S + 2)·B``,
    ``L = 6·S·B``."""
    S = int(sides)
    edges = bn.bone_edges(parents)
    parent_bone = bn.bone_parents(parents)
    B = len(edges)
    P0 = np.asarray(rest_pos, np.float64)
    seg = P0[edges[:, 1]] - P0[edges[:, 0]]
    length = np.linalg.norm(seg, axis=1)
    axis_x, axis_y, axis_z = rest[:, :, 0], rest[:, :, 1], rest[:, :, 2]
    ext = np.where(parent_bone >= 0, np.minimum(r_head, 0.5 * length[np.maximum(parent_bone, 0)]), 0.0)

    # arc length from the trunk base to every node, at rest (parents before children by depth)
    arc = np.zeros(len(parents))
    depth = bn.bone_depths(parent_bone)
    for d in range(depth.max() + 1):
        idx = np.flatnonzero(depth == d)
        arc[edges[idx, 1]] = arc[edges[idx, 0]] + length[idx]
    tile = 2 * math.pi * max(float(np.max(r_head)), 1e-6)
    v_head = (arc[edges[:, 0]] - ext) / tile
    v_tail = arc[edges[:, 1]] / tile

    theta = 2 * math.pi * np.arange(S) / S
    ring = np.cos(theta)[None, :, None] * axis_x[:, None] + np.sin(theta)[None, :, None] * axis_z[:, None]
    head_c = P0[edges[:, 0]] - axis_y * ext[:, None]
    tail_c = P0[edges[:, 1]]
    co = np.concatenate([head_c[:, None] + r_head[:, None, None] * ring,
                         tail_c[:, None] + r_tail[:, None, None] * ring], axis=1)     # (B, 2S, 3)

    k = np.arange(S)
    kn = (k + 1) % S
    side = np.stack([k, S + k, S + kn, kn], axis=1).ravel()                          # outward normals
    head_cap = k                                                                     # normal -Y
    tail_cap = S + k[::-1]                                                           # normal +Y
    per_bone = np.concatenate([side, head_cap, tail_cap])                            # (6S,)
    loop_vert = (per_bone[None] + 2 * S * np.arange(B)[:, None]).ravel()
    totals = np.concatenate([np.full(S, 4), [S, S]])
    starts = np.concatenate([[0], np.cumsum(totals)[:-1]])
    loop_start = (starts[None] + 6 * S * np.arange(B)[:, None]).ravel()
    loop_total = np.tile(totals, B)
    smooth = np.tile(np.concatenate([np.ones(S, bool), [False, False]]), B)

    u_side = np.stack([k, k, k + 1, k + 1], axis=1).ravel() / S                      # (4S,)
    v_side = np.array([0.0, 1.0, 1.0, 0.0])[None].repeat(S, 0).ravel()              # 0 head, 1 tail
    u_cap = 0.5 + np.cos(theta) / (2 * math.pi)
    uv = np.empty((B, 6 * S, 2))
    uv[:, :4 * S, 0] = u_side
    uv[:, :4 * S, 1] = v_head[:, None] + v_side[None] * (v_tail - v_head)[:, None]
    uv[:, 4 * S:5 * S, 0] = u_cap
    uv[:, 4 * S:5 * S, 1] = v_head[:, None] + (r_head[:, None] / tile) * np.sin(theta)[None]
    uv[:, 5 * S:, 0] = u_cap[::-1]
    uv[:, 5 * S:, 1] = v_tail[:, None] + (r_tail[:, None] / tile) * np.sin(theta[::-1])[None]
    return {"co": co.reshape(-1, 3), "loop_vert": loop_vert, "loop_start": loop_start,
            "loop_total": loop_total, "smooth": smooth, "uv": uv.reshape(-1, 2),
            "vert_bone": np.repeat(np.arange(B), 2 * S)}


def _build_mesh(tree: Tree3D, rest: np.ndarray, rig, coll, name: str, material, sides: int,
                created: _Created):
    """The skinned branch mesh object (see :func:`tube_arrays`), parented to ``rig``."""
    r_head, r_tail = branch_radii(tree.parents, tree.radius)
    floor = 1e-4 * max(float(np.ptp(tree.nodes3d[0], axis=0).max()), 1e-3)
    g = tube_arrays(tree.nodes3d[0], tree.parents, rest, np.maximum(r_head, floor),
                    np.maximum(r_tail, floor), sides)
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
    bone_names = bn.bone_names(tree.parents)
    per_bone = 2 * int(sides)
    for b, bname in enumerate(bone_names):
        ob.vertex_groups.new(name=bname).add(list(range(b * per_bone, (b + 1) * per_bone)), 1.0, "REPLACE")
    mod = ob.modifiers.new("Armature", "ARMATURE")
    mod.object = rig
    ob.parent = rig
    return ob


def bark_material(name: str) -> bpy.types.Material:
    """A Principled BSDF bark: brown-grey noise colour, Voronoi bump, UV-mapped (the bark follows
    the bending branches). The caller removes it on failure."""
    mat = bpy.data.materials.new(name)
    try:
        mat.diffuse_color = (0.22, 0.17, 0.13, 1.0)          # solid-view colour
        mat.roughness = 0.9
        if mat.node_tree is None:                            # Blender 4.x; 5.x always has nodes
            mat.use_nodes = True
        nt = mat.node_tree
        nt.nodes.clear()
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
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
        bump.inputs["Strength"].default_value = 0.35
        bsdf.inputs["Roughness"].default_value = 0.9
        link = nt.links.new
        link(coord.outputs["UV"], mapping.inputs["Vector"])
        link(mapping.outputs["Vector"], noise.inputs["Vector"])
        link(mapping.outputs["Vector"], voronoi.inputs["Vector"])
        link(noise.outputs["Fac"], ramp.inputs["Fac"])
        link(ramp.outputs["Color"], bsdf.inputs["Base Color"])
        link(voronoi.outputs["Distance"], bump.inputs["Height"])
        link(bump.outputs["Normal"], bsdf.inputs["Normal"])
        link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    except BaseException:
        bpy.data.materials.remove(mat)
        raise
    return mat
