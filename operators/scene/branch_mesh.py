"""The tree's branch mesh in Blender: tapered tubes along the bones (geometry from
:mod:`core.detail.branch_mesh`), one vertex group per bone, skinned to the armature."""
from __future__ import annotations

import bpy
import numpy as np

from ...core import bones
from ...core.detail import branch_mesh as bm
from ...core.detail.branch_mesh import branch_radii, tube_arrays
from ...core.tree3d import Tree3D
from .objects import Created


def mesh_params(tree: Tree3D, sides: int = 8, curliness: float | None = None, bark: str | None = None,
                seed: int | None = None) -> bm.MeshParams:
    """The branch mesh settings: the given ones, else those recorded in ``tree.meta["mesh"]``
    (``curliness``, ``bark``, ``seed``; written by ``pipeline.build_3d``), else straight plain tubes."""
    rec = tree.meta.get("mesh") or {}
    return bm.MeshParams(sides=sides,
                         curliness=float(rec.get("curliness", 0.0) if curliness is None else curliness),
                         bark=str(rec.get("bark", "none") if bark is None else bark),
                         seed=int(rec.get("seed", 0) if seed is None else seed))


def build_mesh(tree: Tree3D, rest: np.ndarray, rig, coll, name: str, material, params: bm.MeshParams,
               created: Created):
    """The skinned branch mesh object (see :func:`core.detail.branch_mesh.tube_arrays`), parented to
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
