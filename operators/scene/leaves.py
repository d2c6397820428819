"""Leaf clusters in Blender, copied from the asset (:mod:`core.asset`): the leaf bones' flutter
keys and one skinned leaf mesh with its flap shape keys.

Why bones: the flutter ``A(t) sin(ωt + β)`` of every cluster is a keyed rotation of its own bone
(child of the branch bone it sits on, about the cluster's main axis = the bone's Y), and the leaf
cards are one mesh skinned to those bones. A skinned mesh on one armature is what FBX, glTF and
USD (UsdSkel) all carry with its animation; per-object keys would give thousands of objects. The
cost is one bone per cluster (``LeafParams.max_clusters`` caps it). The leaf material is in
:mod:`.materials`.
"""
from __future__ import annotations

import bpy
import numpy as np

from ...core.asset.meshes import LeafFlap, LeafMesh
from ...core.asset.rig import LeafKeys
from ...core.asset.rig import leaf_bone_names as leaf_bone_names  # noqa: PLC0414  (re-exported for scripts)
from . import action_api
from .objects import new_mesh, weight_by_bone

#: the flap shape keys' names (USD-safe), as the asset names them
FLAP_KEYS = LeafFlap.names


def key_leaf_bones(make_fcurve, keys: LeafKeys, names: list[str]) -> None:
    """Key every leaf bone's flutter, LINEAR, in bulk: the rows of ``keys.keep`` per bone (all
    without), with a *Cycles* modifier when the keys are one period. Only the W and Y channels —
    a turn about the bone's own Y axis leaves X and Z at their rest value 0, and half the F-curves
    is half the keying time of a leafy forest."""
    for s, name in enumerate(names):
        path = f'pose.bones["{bpy.utils.escape_identifier(name)}"].rotation_quaternion'
        rows = slice(None) if keys.keep is None else keys.keep[:, s]
        for i in (0, 2):
            fc = make_fcurve(path, i, name)
            action_api.write_keys(fc, keys.frames[rows], keys.q[rows, s, i])
            if keys.cyclic:
                fc.modifiers.new("CYCLES")


def build_leaf_mesh(mesh: LeafMesh, rig, coll, name: str, names: list[str], material, created):
    """The leaf cards as one mesh (quads, UVs, the colour per vertex in ``"Col"``), each vertex
    weighted 1.0 to its leaf bone (``names[mesh.bone]``); Armature modifier, parented to ``rig``,
    the flap's shape keys. ``created`` collects the data-blocks for rollback."""
    V = len(mesh.co)
    me = new_mesh(name, mesh.co, np.arange(V), np.full(mesh.quads, 4), created)
    uv = me.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", mesh.uv.astype(np.float32).ravel())
    col = me.color_attributes.new("Col", "BYTE_COLOR", "POINT")
    rgba = np.concatenate([mesh.colour, np.ones((V, 1))], axis=1).astype(np.float32)
    col.data.foreach_set("color_srgb", rgba.ravel())
    me.materials.append(material)
    me.update()

    ob = created.add(bpy.data.objects, bpy.data.objects.new(name, me))
    coll.objects.link(ob)
    weight_by_bone(ob, mesh.bone, names)
    mod = ob.modifiers.new("Armature", "ARMATURE")
    mod.object = rig
    ob.parent = rig
    if mesh.flap is not None:
        add_leaf_flap(ob, mesh.flap, mesh.co, name, created)
    return ob


def add_leaf_flap(ob, flap: LeafFlap, co: np.ndarray, name: str, created) -> None:
    """Every leaf's own flap about its stem: the four shape keys of ``flap`` keyed with its
    weights on frames ``1..F``, so each card turns by ``leaf_angle · sin(ωt + φ_leaf)`` before the
    cluster bone carries it. Shape keys on a skinned mesh are what FBX (blend shapes), glTF (morph
    targets) and USD (UsdSkel blend shapes) keep with their animation."""
    ob.shape_key_add(name="Basis", from_mix=False)
    for key_name, d in zip(flap.names, flap.offsets):
        kb = ob.shape_key_add(name=key_name, from_mix=False)
        kb.slider_min, kb.slider_max = 0.0, 1.0
        kb.data.foreach_set("co", (co + d).astype(np.float32).ravel())
    keys = ob.data.shape_keys
    action, make_fcurve = action_api.new_action(keys, f"{name} Flap")
    created.add(bpy.data.actions, action)
    frames = np.arange(1, len(flap.weights) + 1, dtype=np.float32)
    for i, key_name in enumerate(flap.names):
        path = f'key_blocks["{bpy.utils.escape_identifier(key_name)}"].value'
        action_api.write_keys(make_fcurve(path, 0, "Leaf flap"), frames, flap.weights[:, i])
