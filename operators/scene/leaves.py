"""Leaf clusters in Blender: one bone per cluster and one skinned leaf mesh.

Why bones: the flutter ``A(t) sin(ωt + β)`` of every cluster is a keyed rotation of its own bone
(child of the branch bone it sits on, about the cluster's main axis = the bone's Y), and the leaf
cards are one mesh skinned to those bones. A skinned mesh on one armature is what FBX, glTF and
USD (UsdSkel) all carry with its animation; per-object keys would give thousands of objects and
shape keys do not survive USD/glTF skinning. The cost is one bone per cluster (``LeafParams.
max_clusters`` caps it). The leaf material is in :mod:`.materials`.
"""
from __future__ import annotations

import bpy
import numpy as np

from ...core import bones
from ...core.detail.leaf_clusters import flap_weights, leaf_flap_offsets, leaf_mesh
from ...core.keys import SteadyFlutter, flutter_quaternions
from ...core.tree3d import Tree3D
from . import action_api
from .materials import leaf_tint


def leaf_bone_names(count: int) -> list[str]:
    return [f"L{k:04d}" for k in range(count)]


def add_leaf_edit_bones(data, tree: Tree3D) -> list[str]:
    """With the armature ``data`` in edit mode, one bone per leaf cluster: head at the cluster
    centre, tail along its main axis (``radius`` long), parented (not connected) to the bone of the
    cluster's node. Returns the bone names (``L0000``…) in cluster order."""
    lv = tree.leaves
    names = leaf_bone_names(lv.count)
    parent_names = {int(c): n for c, n in zip(bones.bone_edges(tree.parents)[:, 1], bones.bone_names(tree.parents))}
    missing = sorted(set(int(n) for n in np.unique(lv.node)) - set(parent_names))
    if missing:
        raise RuntimeError(f"leaf clusters sit on nodes without a bone: {missing[:5]}")
    ebones = data.edit_bones
    existing = {b.name: b for b in ebones}
    new = [ebones.new(n) for n in names]
    head = lv.pos.astype(np.float32)
    tail = head + lv.axis.astype(np.float32) * np.float32(max(lv.radius, 1e-4))
    ebones.foreach_set("head", np.concatenate([_edit_get(ebones, "head", len(existing)), head.ravel()]))
    ebones.foreach_set("tail", np.concatenate([_edit_get(ebones, "tail", len(existing)), tail.ravel()]))
    ebones.foreach_set("roll", np.zeros(len(ebones), np.float32))
    for eb, node in zip(new, lv.node):
        eb.parent = existing[parent_names[int(node)]]
        eb.use_connect = False
        eb.use_deform = True
    if hasattr(data, "collections"):               # Blender 4.0+: leaf bones in a hidden bone collection
        bcoll = data.collections.new("Leaves")      # (hundreds of sticks would hide the tree in the viewport)
        for eb in new:
            bcoll.assign(eb)
        bcoll.is_visible = False
    return names


def _edit_get(ebones, attr: str, n_old: int) -> np.ndarray:
    """The first ``n_old`` bones' ``attr`` as a flat float32 array (foreach_set needs all bones)."""
    flat = np.empty(len(ebones) * 3, np.float32)
    ebones.foreach_get(attr, flat)
    return flat[: n_old * 3]


def key_leaf_bones(rig, make_fcurve, tree: Tree3D, names: list[str], frames: np.ndarray | None = None,
                   keep: np.ndarray | None = None, cycle: SteadyFlutter | None = None) -> None:
    """Key every leaf bone's flutter, LINEAR, in bulk: with ``cycle`` (:func:`core.keys.tree_keys`)
    one period of its steady flutter from the first frame, repeated by a *Cycles* modifier; else at
    scene ``frames (F,)`` (default ``1..F``), only those of ``keep (F, S)`` (default every frame).
    Only the W and Y channels — a turn about the bone's own Y axis leaves X and Z at their rest
    value 0, and half the F-curves is half the keying time of a leafy forest."""
    frames = np.arange(1, tree.n_frames + 1, dtype=np.float32) if frames is None else np.asarray(frames, np.float32)
    if cycle is not None:
        q = flutter_quaternions(cycle.angles)
        frames, keep = (frames[0] + cycle.frames).astype(np.float32), None
    else:
        q = flutter_quaternions(tree.leaves.flutter)
    for s, name in enumerate(names):
        path = f'pose.bones["{bpy.utils.escape_identifier(name)}"].rotation_quaternion'
        rows = slice(None) if keep is None else keep[:, s]
        for i in (0, 2):
            fc = make_fcurve(path, i, name)
            action_api.write_keys(fc, frames[rows], q[rows, s, i])
            if cycle is not None:
                fc.modifiers.new("CYCLES")


def build_leaf_mesh(tree: Tree3D, rig, coll, name: str, names: list[str], material, created):
    """The leaf cards of all clusters as one mesh (quads, UVs, the video's colour per vertex in
    ``"Col"``), each cluster's vertices weighted 1.0 to its bone; Armature modifier, parented to
    ``rig``. ``created`` collects the data-blocks for rollback."""
    g = leaf_mesh(tree.leaves)
    V = len(g["co"])
    me = created.add(bpy.data.meshes, bpy.data.meshes.new(name))
    me.vertices.add(V)
    me.vertices.foreach_set("co", g["co"].astype(np.float32).ravel())
    me.loops.add(V)
    me.loops.foreach_set("vertex_index", np.arange(V, dtype=np.int32))
    Q = g["quads"]
    me.polygons.add(Q)
    me.polygons.foreach_set("loop_start", np.arange(0, 4 * Q, 4, dtype=np.int32))
    me.polygons.foreach_set("loop_total", np.full(Q, 4, np.int32))
    me.update(calc_edges=True)
    uv = me.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", g["uv"].astype(np.float32).ravel())
    col = me.color_attributes.new("Col", "BYTE_COLOR", "POINT")
    rel = np.clip(g["colour"] / leaf_tint(tree.leaves), 0.0, 1.0)      # texture × this = the video's colour
    rgba = np.concatenate([rel, np.ones((V, 1))], axis=1).astype(np.float32)
    col.data.foreach_set("color_srgb", rgba.ravel())
    me.materials.append(material)
    me.update()

    ob = created.add(bpy.data.objects, bpy.data.objects.new(name, me))
    coll.objects.link(ob)
    per = V // max(tree.leaves.count, 1)
    for s, bname in enumerate(names):
        ob.vertex_groups.new(name=bname).add(range(s * per, (s + 1) * per), 1.0, "REPLACE")
    mod = ob.modifiers.new("Armature", "ARMATURE")
    mod.object = rig
    ob.parent = rig
    add_leaf_flap(ob, tree, g["co"], name, created)
    return ob


FLAP_KEYS = ("Leaf flap sin pos", "Leaf flap sin neg", "Leaf flap cos pos", "Leaf flap cos neg")   # USD-safe names


def add_leaf_flap(ob, tree: Tree3D, co: np.ndarray, name: str, created) -> None:
    """Every leaf's own flap about its stem: four shape keys (+C, −C, +S, −S of
    :func:`core.leaves.leaf_flap_offsets`) keyed with :func:`core.leaves.flap_weights`, so each
    card turns by ``leaf_angle · sin(ωt + φ_leaf)`` before the cluster bone carries it. Shape keys
    on a skinned mesh are what FBX (blend shapes), glTF (morph targets) and USD (UsdSkel blend
    shapes) keep with their animation."""
    lv = tree.leaves
    if lv.leaf_angle <= 0 or lv.leaf_hz <= 0:
        return
    C, S, _ = leaf_flap_offsets(co, lv.leaf_angle, lv.seed)
    ob.shape_key_add(name="Basis", from_mix=False)
    for key_name, d in zip(FLAP_KEYS, (C, -C, S, -S)):
        kb = ob.shape_key_add(name=key_name, from_mix=False)
        kb.slider_min, kb.slider_max = 0.0, 1.0
        kb.data.foreach_set("co", (co + d).astype(np.float32).ravel())
    keys = ob.data.shape_keys
    action, make_fcurve = action_api.new_action(keys, f"{name} Flap")
    created.add(bpy.data.actions, action)
    w = flap_weights(tree.n_frames, tree.fps, lv.leaf_hz)
    frames = np.arange(1, tree.n_frames + 1, dtype=np.float32)
    for i, key_name in enumerate(FLAP_KEYS):
        path = f'key_blocks["{bpy.utils.escape_identifier(key_name)}"].value'
        action_api.write_keys(make_fcurve(path, 0, "Leaf flap"), frames, w[:, i])


