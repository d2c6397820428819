"""A tree-cut's branch mesh (:class:`~core.tree_cut.CutMesh`): the polygons of the source tree's
branch mesh (:func:`.meshes.branch_arrays`, the look its ``meta["mesh"]`` records) whose every
vertex rides on one of the cut's bones, moved so the cut's base is the origin. What Save Cut keeps
beside the skeleton: how the cut looked where it was cut from."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .. import bones
from ..tree3d import Tree3D
from ..tree_cut import CutMesh, TreeCut
from .look import mesh_params
from .meshes import branch_arrays


def with_mesh(tree: Tree3D, cut: TreeCut) -> TreeCut:
    """``cut`` (made from ``tree`` by :func:`core.tree_cut.cut_from_tree`) with its :class:`CutMesh`."""
    rest_pos = np.asarray(tree.nodes3d[0], np.float64)
    mesh = branch_arrays(tree, bones.rest_frames(tree.parents, rest_pos), mesh_params(tree))
    child = bones.bone_edges(tree.parents)[:, 1]                       # bone b drives node child[b]
    where = -np.ones(tree.n_nodes, np.int64)
    where[np.asarray(cut.source_nodes[1:], np.int64)] = np.arange(1, len(cut.source_nodes))
    vert_node = where[child[mesh.bone]]                                # (V,) cut node, -1 outside
    inside = vert_node[mesh.loop_vert] >= 0
    poly_in = np.logical_and.reduceat(inside, mesh.loop_start) if len(mesh.loop_start) else np.zeros(0, bool)
    totals = mesh.loop_total[poly_in]
    loops = np.flatnonzero(np.repeat(poly_in, mesh.loop_total))         # polygons' loops are contiguous, in order
    used = np.unique(mesh.loop_vert[loops])
    remap = -np.ones(len(mesh.co), np.int64)
    remap[used] = np.arange(len(used))
    base = rest_pos[int(cut.source_nodes[0])]
    out = CutMesh((mesh.co[used] - base).astype(np.float32), remap[mesh.loop_vert[loops]].astype(np.int32),
                  (np.cumsum(totals) - totals).astype(np.int32), totals.astype(np.int32),
                  vert_node[used].astype(np.int32))
    return replace(cut, mesh=out)
