"""A tree-cut (seed 001 §3): a part of a tree kept in a file to be placed, unchanged, in new
trees (:mod:`.generate.cuts` places it; :func:`.asset.cut_mesh.with_mesh` adds the branch mesh its
source drew).

A cut is a subtree: the bones chosen (with ``whole_branch``, every bone beyond them too: a branch
with its side branches) hanging from one joint, its *base* (the head of its first bones). It keeps
the rest pose of its nodes relative to the base (metres, the source's axes: x right, y depth, z
up), their radii (metres), the direction of the bone it hung from (``parent_dir``: the angle it
leaves its parent at), where it came from, and its branch mesh. The file is an ``.npz`` of those
arrays with a JSON header (``meta_json``), never pickle.
"""
from __future__ import annotations

import io
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError
from .fileio import atomic_write_bytes
from .topology import subtree, topological_order

FORMAT = "tree_from_video.cut"
VERSION = 1
UP = np.array([0.0, 0.0, 1.0])


@dataclass
class CutMesh:
    """A cut's branch mesh as its source drew it, metres from the base in the source's axes:
    ``co (V, 3)``; polygons as ``loop_vert (L,)``, ``loop_start``, ``loop_total (P,)``;
    ``node (V,)`` the cut node (index into the cut) whose bone drives each vertex."""

    co: np.ndarray
    loop_vert: np.ndarray
    loop_start: np.ndarray
    loop_total: np.ndarray
    node: np.ndarray


@dataclass
class TreeCut:
    """A part of a tree (module docstring). ``parents (M,)`` int32 within the cut, -1 for node 0
    (the base, where it joined its source); ``rest (M, 3)`` float64 metres from the base;
    ``radius (M,)`` metres (the base's: the source's radius there); ``parent_dir (3,)`` unit
    direction of the source bone into the base (up for a cut from the root); ``source`` the source
    tree's name, ``source_nodes (M,)`` its node indices; ``mesh`` the branch mesh (None: not made)."""

    parents: np.ndarray
    rest: np.ndarray
    radius: np.ndarray
    parent_dir: np.ndarray
    source: str = ""
    source_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    mesh: CutMesh | None = None

    @property
    def n_bones(self) -> int:
        return len(self.parents) - 1

    def bone_lengths(self) -> np.ndarray:
        """``(M-1,)`` metres, bone into node 1..M-1."""
        return bone_lengths(self.parents, self.rest)[1:]


def bone_lengths(parents: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """``(N,)`` metres of the bone into each node (0 for a root)."""
    p = np.asarray(parents)
    out = np.zeros(len(p))
    has = p >= 0
    out[has] = np.linalg.norm(pos[has] - pos[p[has]], axis=1)
    return out


# ----------------------------------------------------------------------------- a cut from a tree

def bone_nodes(tree_parents: np.ndarray, bones: Sequence) -> np.ndarray:
    """The child nodes of ``bones``: names ``"B012"`` (:func:`core.bones.bone_names`) or node indices."""
    n = len(tree_parents)
    out = []
    for b in bones:
        if isinstance(b, str):
            if not (b[:1] == "B" and b[1:].isdigit()):
                raise InputError(f"'{b}' is not a branch bone (they are named B001, B002...); select branch bones")
            b = int(b[1:])
        b = int(b)
        if not 0 < b < n or tree_parents[b] < 0:
            raise InputError(f"bone B{b:03d} is not in this tree of {n - 1} bones")
        out.append(b)
    if not out:
        raise InputError("no bones chosen for the cut; select the bones of a branch (Pose Mode) first")
    return np.unique(out)


def cut_from_tree(tree, bones: Sequence, whole_branch: bool = True) -> TreeCut:
    """The cut of ``tree`` (a :class:`~..tree3d.Tree3D`, its rest pose frame 0) made of ``bones``
    (:func:`bone_nodes`), with every bone beyond them when ``whole_branch``. The chosen bones must
    hang from one joint; else :class:`InputError` saying which pieces there are."""
    parents = np.asarray(tree.parents, np.int64)
    pos = np.asarray(tree.nodes3d[0], np.float64)
    chosen = bone_nodes(parents, bones)
    mask = subtree(parents, chosen) if whole_branch else np.isin(np.arange(len(parents)), chosen)
    mask[0] = mask[0] and parents[0] >= 0
    tops = np.flatnonzero(mask & ~mask[np.maximum(parents, 0)] | (mask & (parents < 0)))
    bases = np.unique(parents[tops])
    if len(bases) != 1:
        raise InputError(f"the chosen bones are {len(bases)} separate pieces (hanging from nodes "
                         f"{', '.join(str(int(b)) for b in bases[:5])}); choose bones of one branch")
    base = int(bases[0])
    nodes = np.concatenate([[base], [n for n in topological_order(parents) if mask[n]]]).astype(np.int64)
    index = -np.ones(len(parents), np.int64)
    index[nodes] = np.arange(len(nodes))
    cut_par = np.where(np.arange(len(nodes)) == 0, -1, index[parents[nodes]])
    pb = parents[base]
    u = UP.copy() if pb < 0 else pos[base] - pos[pb]
    if np.linalg.norm(u) < 1e-12:
        u = UP.copy()
    return TreeCut(cut_par.astype(np.int32), pos[nodes] - pos[base], np.asarray(tree.radius, np.float64)[nodes],
                   u / np.linalg.norm(u), str(getattr(tree, "name", "")), nodes.astype(np.int32))


# ----------------------------------------------------------------------------- files

def cut_bytes(cut: TreeCut) -> bytes:
    """The cut as the bytes of an ``.npz``: its arrays and a JSON header (``meta_json``)."""
    meta = {"format": FORMAT, "version": VERSION, "source": cut.source, "bones": int(cut.n_bones),
            "base_radius_m": float(cut.radius[0]), "reach_m": float(np.linalg.norm(cut.rest, axis=1).max()),
            "units": "metres; rest relative to the base, the source's axes (x right, y depth, z up)"}
    arrays: dict[str, np.ndarray] = dict(parents=cut.parents.astype(np.int32), rest=cut.rest.astype(np.float64),
                  radius=cut.radius.astype(np.float64), parent_dir=cut.parent_dir.astype(np.float64),
                  source_nodes=np.asarray(cut.source_nodes, np.int32), meta_json=np.array(json.dumps(meta)))
    if cut.mesh is not None:
        m = cut.mesh
        arrays.update(mesh_co=m.co.astype(np.float32), mesh_loop_vert=m.loop_vert.astype(np.int32),
                      mesh_loop_start=m.loop_start.astype(np.int32), mesh_loop_total=m.loop_total.astype(np.int32),
                      mesh_node=m.node.astype(np.int32))
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def save_cut(path: str | os.PathLike, cut: TreeCut, overwrite: bool = False) -> None:
    """Write ``cut`` to ``path`` (``.npz``), atomically; an existing file only with ``overwrite``."""
    if os.path.exists(path) and not overwrite:
        raise InputError(f"'{path}' exists; pick another name or allow overwriting")
    atomic_write_bytes(path, cut_bytes(cut))


def load_cut(path: str | os.PathLike) -> TreeCut:
    """The cut in ``path`` (written by :func:`save_cut`); one-line :class:`InputError` otherwise."""
    if not os.path.isfile(path):
        raise InputError(f"cut file '{path}' does not exist; save one with Save Cut (Pose Mode, bones selected)")
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta_json"]))
            if meta.get("format") != FORMAT:
                raise KeyError("format")
            mesh = None
            if "mesh_co" in z.files:
                mesh = CutMesh(z["mesh_co"], z["mesh_loop_vert"], z["mesh_loop_start"], z["mesh_loop_total"],
                               z["mesh_node"])
            cut = TreeCut(z["parents"].astype(np.int32), z["rest"].astype(np.float64), z["radius"].astype(np.float64),
                          z["parent_dir"].astype(np.float64), str(meta.get("source", "")),
                          z["source_nodes"].astype(np.int32), mesh)
    except (KeyError, ValueError, OSError) as exc:
        raise InputError(f"'{path}' is not a Tree from Video cut file ({exc}); save one with Save Cut") from None
    if len(cut.parents) < 2 or cut.parents[0] != -1 or (cut.parents[1:] < 0).any():
        raise InputError(f"cut file '{path}' holds no branch; save the cut again")
    return cut
