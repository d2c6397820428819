"""The tree's branch mesh in Blender, copied from the asset (:class:`core.asset.meshes.
BranchMesh`): tapered tubes along the bones, one vertex group per bone, skinned to the armature."""
from __future__ import annotations

import bpy
import numpy as np

from ...core.asset.look import mesh_params as mesh_params  # noqa: PLC0414  (re-exported for scripts)
from ...core.asset.meshes import BranchMesh
from .objects import Created, new_mesh, weight_by_bone


def build_mesh(mesh: BranchMesh, names: list[str], rig, coll, name: str, material, created: Created):
    """The skinned branch mesh object, parented to ``rig``: one vertex group per bone of
    ``names`` holding its rings (weight 1), bulk-filled by ``foreach_set``."""
    me = new_mesh(name, mesh.co, mesh.loop_vert, mesh.loop_total, created)    # polygons in loop order
    me.polygons.foreach_set("use_smooth", mesh.smooth)
    uv = me.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", mesh.uv.astype(np.float32).ravel())
    me.materials.append(material)
    me.update()

    ob = created.add(bpy.data.objects, bpy.data.objects.new(name, me))
    coll.objects.link(ob)
    weight_by_bone(ob, mesh.bone, names)
    mod = ob.modifiers.new("Armature", "ARMATURE")
    mod.object = rig
    ob.parent = rig
    return ob
