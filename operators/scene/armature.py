"""The tree's armature, copied from the asset's rig (:class:`core.asset.rig.Rig`): its bones built
in one edit-mode session and its pose keyed in QUATERNION mode as the rig's keys say, in bulk
(``foreach_set`` for bones and keys, no per-key Python)."""
from __future__ import annotations

import bpy
import numpy as np

from ...core.asset.rig import BoneKeys, Rig
from . import action_api
from .objects import Created, deselect_all

#: the hidden bone collections of the branch bones and of the leaf bones
BRANCH_BONES = "Branches"
LEAF_BONES = "Leaves"
#: how far Blender's rest rotations may differ from the rig's (float32 heads and tails: ~1e-6)
REST_TOLERANCE = 1e-4


def build_armature(context, rig_data: Rig, coll, name: str, created: Created):
    """Armature object with the rig's bones at rest (roll 0; branch bones connected to their
    parent, leaf bones parented only), in one edit-mode session (each mode switch updates the whole
    view layer, which is what made forests slow); branch and leaf bones in hidden bone collections.
    Checks that Blender's rest rotations are the rig's (its keys are relative to them)."""
    data = created.add(bpy.data.armatures, bpy.data.armatures.new(name))
    data.display_type = "STICK"
    rig = created.add(bpy.data.objects, bpy.data.objects.new(name, data))
    coll.objects.link(rig)
    view_layer = context.view_layer
    deselect_all(view_layer)
    rig.select_set(True)
    view_layer.objects.active = rig
    B = rig_data.n_branch
    with context.temp_override(active_object=rig, object=rig, edit_object=rig):   # also in a scratch scene
        bpy.ops.object.mode_set(mode="EDIT")
        try:
            new = _edit_bones(data, rig_data)
            hide_bones(data, new[:B], BRANCH_BONES)
            if len(new) > B:
                hide_bones(data, new[B:], LEAF_BONES)
        finally:
            bpy.ops.object.mode_set(mode="OBJECT")

    order = {b.name: i for i, b in enumerate(data.bones)}
    if len(order) != len(rig_data.names):
        raise RuntimeError(f"the armature has {len(order)} bones, expected {len(rig_data.names)}")
    flat = np.empty(len(order) * 16, np.float32)
    data.bones.foreach_get("matrix_local", flat)
    mats = flat.reshape(-1, 4, 4).transpose(0, 2, 1)         # foreach_get is column-major
    rest = mats[[order[n] for n in rig_data.names[:B]], :3, :3].astype(np.float64)
    off = float(np.abs(rest - rig_data.rest).max()) if B else 0.0
    if off > REST_TOLERANCE:
        raise RuntimeError(f"Blender's bone rest rotations differ from the rig's by {off:.2g}; "
                           "this Blender's roll convention is not the one core.bones.rest_frames follows")
    quaternion = bpy.types.PoseBone.bl_rna.properties["rotation_mode"].enum_items["QUATERNION"].value
    rig.pose.bones.foreach_set("rotation_mode", np.full(len(order), quaternion, np.int32))
    return rig


def hide_bones(data, edit_bones: list, name: str) -> None:
    """In edit mode: put ``edit_bones`` in a new, hidden bone collection ``name`` of the armature
    ``data`` (Blender 4.0+), so the viewport draws none of them (black sticks would poke out of
    every branch tip, hundreds of leaf sticks would hide the tree) while every export keeps them,
    with their names and keys (exporters ignore bone collections). Armature properties › Bone
    Collections shows them again."""
    if not hasattr(data, "collections"):
        return
    bcoll = data.collections.new(name)
    for eb in edit_bones:
        bcoll.assign(eb)
    bcoll.is_visible = False


def _edit_bones(data, rig_data: Rig) -> list:
    """In edit mode: the rig's bones from its heads and tails (metres), roll 0, each parented to
    its parent bone (connected where the rig says: its head is the parent's tail). Returns the new
    edit bones in the rig's order."""
    ebones = data.edit_bones
    new = [ebones.new(n) for n in rig_data.names]
    ebones.foreach_set("head", np.asarray(rig_data.head, np.float32).ravel())
    ebones.foreach_set("tail", np.asarray(rig_data.tail, np.float32).ravel())
    ebones.foreach_set("roll", np.zeros(len(new), np.float32))
    for eb, pb, connected in zip(new, rig_data.parent, rig_data.connected):
        if pb >= 0:
            eb.parent = new[pb]
            eb.use_connect = bool(connected)
    return new


def key_pose(rig, keys: BoneKeys, names: list[str], action_name: str, created: Created):
    """Key the branch bones ``names`` as ``keys`` say: baked samples for the sampled bones, Bezier
    keys with the rig's handles on the kept frames (they play :func:`core.keys.interpolate`), or
    LINEAR keys on every frame; their locations too where the keys carry them (a bone budget).
    Returns the action and its F-curve maker."""
    action, make_fcurve = action_api.new_action(rig, action_name)
    created.add(bpy.data.actions, action)
    pose_index = {pb.name: i for i, pb in enumerate(rig.pose.bones)}
    local, frames = keys.local, keys.frames
    for b, name in enumerate(names):
        if name not in pose_index:
            raise RuntimeError(f"pose bone {name} is missing")
        path = f'pose.bones["{bpy.utils.escape_identifier(name)}"].rotation_quaternion'
        for i in range(4):
            fc = make_fcurve(path, i, name)
            if keys.keep is None:
                action_api.write_keys(fc, frames, local[:, b, i])
            elif keys.sampled[b]:
                action_api.write_samples(fc, int(frames[0]), local[:, b, i])
            else:
                assert keys.left is not None and keys.right is not None
                rows = keys.keep[:, b]
                action_api.write_keys(fc, frames[rows], local[rows, b, i],
                                      (keys.left[rows, b, i], keys.right[rows, b, i]))
        if keys.location is not None:           # a re-fitted bone (a bone budget) moves as well as turns
            path = f'pose.bones["{bpy.utils.escape_identifier(name)}"].location'
            for i in range(3):
                action_api.write_keys(make_fcurve(path, i, name), frames, keys.location[:, b, i])
    return action, make_fcurve
