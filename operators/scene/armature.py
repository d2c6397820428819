"""The tree's armature: one connected bone per edge at the frame-0 positions (built in one
edit-mode session) and its pose keyed in QUATERNION mode where the motion needs keys
(:mod:`core.keys`), in bulk (``foreach_set``
for bones and keys, no per-key Python)."""
from __future__ import annotations

import bpy
import numpy as np

from ...core import bones, keys
from ...core.tree3d import Tree3D
from . import action_api
from .objects import Created, deselect_all

#: the hidden bone collection of the branch bones (the leaf bones have their own, "Leaves")
BRANCH_BONES = "Branches"


def build_armature(context, tree: Tree3D, coll, name: str, created: Created, extra_edit=None):
    """Armature object with one connected bone per edge at frame-0 positions; ``extra_edit(data)``
    adds more bones in the same edit-mode session (each mode switch updates the whole view layer,
    which is what made forests slow).

    Returns ``(object, rest (B, 3, 3), extra)``: rest rotations read back from ``bone.matrix_local``
    in :func:`bones.bone_edges` order, and what ``extra_edit`` returned (its bone names)."""
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
            branch_bones = _edit_bones(data, names, rest_pos[edges[:, 0]], rest_pos[edges[:, 1]], parent_bone)
            hide_bones(data, branch_bones, BRANCH_BONES)
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


def hide_bones(data, edit_bones: list, name: str) -> None:
    """In edit mode: put ``edit_bones`` in a new, hidden bone collection ``name`` of the armature
    ``data`` (Blender 4.0+), so the viewport draws none of them (black sticks would poke out of
    every branch tip) while every export keeps them, with their names and keys (exporters ignore
    bone collections). Armature properties › Bone Collections shows them again."""
    if not hasattr(data, "collections"):
        return
    bcoll = data.collections.new(name)
    for eb in edit_bones:
        bcoll.assign(eb)
    bcoll.is_visible = False


def _edit_bones(data, names: list[str], heads: np.ndarray, tails: np.ndarray, parent_bone: np.ndarray) -> list:
    """In edit mode: bones ``names`` from ``heads``/``tails (B, 3)`` metres, roll 0, each connected
    to ``parent_bone`` (-1: none): its head is the parent's tail, the node they share. Returns the
    new edit bones."""
    ebones = data.edit_bones
    new = [ebones.new(n) for n in names]
    ebones.foreach_set("head", np.asarray(heads, np.float32).ravel())
    ebones.foreach_set("tail", np.asarray(tails, np.float32).ravel())
    ebones.foreach_set("roll", np.zeros(len(names), np.float32))
    for eb, pb in zip(new, parent_bone):
        if pb >= 0:
            eb.parent = new[pb]
            eb.use_connect = True
    return new


def key_pose(rig, local: np.ndarray, names: list[str], action_name: str, created: Created,
             frames: np.ndarray | None = None, keep: np.ndarray | None = None):
    """Key ``local (F, B, 4)`` quaternions on the rig's pose bones at scene ``frames (F,)`` (default
    ``1..F``; a variable-frame-rate clip's keys sit at its frames' times, :func:`key_frames`):
    with ``keep (F, B)`` (:func:`core.keys.tree_keys`) a bone keeping every frame of an evenly timed
    clip as baked samples, any other as Bezier keys on its kept frames with the handles that play
    :func:`core.keys.interpolate`; without, LINEAR keys on every frame."""
    action, make_fcurve = action_api.new_action(rig, action_name)
    created.add(bpy.data.actions, action)
    frames = np.arange(1, len(local) + 1, dtype=np.float32) if frames is None else np.asarray(frames, np.float32)
    pose_index = {pb.name: i for i, pb in enumerate(rig.pose.bones)}
    even = bool(np.all(np.diff(frames) == 1.0)) and float(frames[0]).is_integer()
    sampled = keep.all(axis=0) & even if keep is not None else np.zeros(len(names), bool)
    if keep is not None:
        left, right = keys.handles(local, keep, frames)
    for b, name in enumerate(names):
        if name not in pose_index:
            raise RuntimeError(f"pose bone {name} is missing")
        path = f'pose.bones["{bpy.utils.escape_identifier(name)}"].rotation_quaternion'
        for i in range(4):
            fc = make_fcurve(path, i, name)
            if keep is None:
                action_api.write_keys(fc, frames, local[:, b, i])
            elif sampled[b]:
                action_api.write_samples(fc, int(frames[0]), local[:, b, i])
            else:
                rows = keep[:, b]
                action_api.write_keys(fc, frames[rows], local[rows, b, i],
                                      (left[rows, b, i], right[rows, b, i]))
    return action, make_fcurve
