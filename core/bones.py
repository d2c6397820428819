"""Bones of an animated :class:`~.tree3d.Tree3D`: topology and per-frame local pose rotations.

Pure numpy (no bpy), so it runs in tests, batch jobs and worker threads.

Conventions
-----------
* One bone per edge ``(parent node -> child node)``, in :meth:`Tree3D.edges` order (children
  ascending); bone ``b`` is named ``"B{child:03d}"``. A bone's parent bone is the bone that ends at
  its head node; bones that start at a root node (``parents == -1``, the trunk base) have none.
* The rest pose is frame 0. Positions are metres in armature space (x right, y depth, z up).
* Quaternions are ``(w, x, y, z)`` arrays, last axis 4, unit length, float64 (:mod:`.rotations`).
* ``rest_matrices (B, 3, 3)`` are the rotation parts of the bones' rest matrices in armature
  space (Blender's ``Bone.matrix_local``): column 1 (the bone's Y axis) points from head to tail.

Only rotations are animated: bone lengths stay those of frame 0 and the root node stays where it
is, so a tail's error is the drift of the input's edge lengths accumulated along its chain
(:func:`length_drift`).
"""
from __future__ import annotations

import numpy as np

from .errors import InputError
from .rotations import (
    make_continuous,
    matrix_to_quat,
    quat_conj,
    quat_mul,
    quat_rotate,
    quat_to_matrix,
    swing,
)
from .topology import edges_of

#: Directions shorter than this (metres) have no usable orientation.
EPS_LENGTH = 1e-9


# ----------------------------------------------------------------------------- topology

def bone_edges(parents: np.ndarray) -> np.ndarray:
    """``(B, 2)`` int (head node, tail node) for every node with a parent: one bone each."""
    return edges_of(parents).astype(np.int64)


def bone_names(parents: np.ndarray) -> list[str]:
    """Bone names ``"B{child:03d}"`` in :func:`bone_edges` order."""
    return [f"B{c:03d}" for c in bone_edges(parents)[:, 1]]


def bone_parents(parents: np.ndarray) -> np.ndarray:
    """``(B,)`` int: index of each bone's parent bone (the bone ending at its head), -1 for none."""
    parents = np.asarray(parents)
    edges = bone_edges(parents)
    bone_of_node = np.full(len(parents), -1, np.int64)
    bone_of_node[edges[:, 1]] = np.arange(len(edges))
    return bone_of_node[edges[:, 0]]


def bone_depths(parent_bone: np.ndarray) -> np.ndarray:
    """``(B,)`` int: 0 for bones without a parent bone, else the parent's depth + 1.

    Raises :class:`InputError` if the bone parents contain a cycle."""
    parent_bone = np.asarray(parent_bone)
    depth = np.where(parent_bone < 0, 0, -1)
    for _ in range(len(parent_bone) + 1):
        todo = depth < 0
        if not todo.any():
            return depth
        ready = todo & (depth[np.maximum(parent_bone, 0)] >= 0)
        if not ready.any():
            break
        depth[ready] = depth[parent_bone[ready]] + 1
    raise InputError("the tree's parent links contain a cycle; every node must lead back to the trunk base")


# ----------------------------------------------------------------------------- poses

def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, EPS_LENGTH), n[..., 0]


def check_positions(parents: np.ndarray, nodes3d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Validate ``nodes3d (F, N, 3)`` for ``parents (N,)``: shape, finite values, at least one
    bone, no zero-length bone in frame 0 (Blender deletes those). Returns the arrays as numpy
    (positions float64); raises :class:`InputError` naming the problem."""
    parents = np.asarray(parents)
    nodes3d = np.asarray(nodes3d, np.float64)
    if nodes3d.ndim != 3 or nodes3d.shape[1:] != (len(parents), 3) or len(nodes3d) == 0:
        raise InputError(f"node positions have shape {nodes3d.shape}, expected (frames, {len(parents)}, 3); "
                         "the 3D tree file is inconsistent: rebuild it")
    if not np.isfinite(nodes3d).all():
        raise InputError("the 3D tree has non-finite node positions (NaN/inf); rebuild it from the video")
    edges = bone_edges(parents)
    if len(edges) == 0:
        raise InputError("the 3D tree has no branches (a single node); trace a skeleton with at least two nodes")
    _, length = _unit(nodes3d[0, edges[:, 1]] - nodes3d[0, edges[:, 0]])
    short = np.flatnonzero(length < 1e-6)
    if len(short):
        raise InputError(f"bone B{edges[short[0], 1]:03d} has zero length in the first frame (nodes "
                         f"{edges[short[0], 0]} and {edges[short[0], 1]} coincide); rebuild the 3D tree")
    return parents, nodes3d


def world_rotations(parents: np.ndarray, nodes3d: np.ndarray) -> np.ndarray:
    """World (armature-space) pose rotations relative to the rest pose, ``(F, B, 4)``.

    ``parents (N,)``, ``nodes3d (F, N, 3)`` metres, frame 0 = rest. A bone inherits its parent
    bone's rotation, then swings minimally from that rotated rest direction to its direction at
    frame t, so no twist accumulates down the tree. Bones of equal depth are processed together,
    vectorised over frames. A bone that collapses to zero length in some frame keeps its
    inherited rotation there."""
    parents, nodes3d = check_positions(parents, nodes3d)
    edges = bone_edges(parents)
    parent_bone = bone_parents(parents)
    depth = bone_depths(parent_bone)
    rest_dir, _ = _unit(nodes3d[0, edges[:, 1]] - nodes3d[0, edges[:, 0]])          # (B, 3)
    cur_dir, cur_len = _unit(nodes3d[:, edges[:, 1]] - nodes3d[:, edges[:, 0]])     # (F, B, 3)
    F, B = cur_dir.shape[:2]
    q = np.zeros((F, B, 4))
    for d in range(depth.max() + 1):
        idx = np.flatnonzero(depth == d)
        if d == 0:
            inherited = np.zeros((F, len(idx), 4))
            inherited[..., 0] = 1.0
        else:
            inherited = q[:, parent_bone[idx]]
        carried = quat_rotate(inherited, rest_dir[idx])                            # (F, n, 3)
        target = np.where(cur_len[:, idx, None] < EPS_LENGTH, carried, cur_dir[:, idx])
        qb = quat_mul(swing(carried, target), inherited)
        q[:, idx] = qb / np.linalg.norm(qb, axis=-1, keepdims=True)
    return q


def local_rotations(parents: np.ndarray, nodes3d: np.ndarray, rest_matrices: np.ndarray) -> np.ndarray:
    """Pose-bone quaternions (Blender's ``PoseBone.rotation_quaternion``), ``(F, B, 4)`` float64.

    ``L(b) = R_rest(b)ᵀ · Q_w(parent)ᵀ · Q_w(b) · R_rest(b)`` with ``Q_w`` from
    :func:`world_rotations` and ``R_rest = rest_matrices (B, 3, 3)`` (Blender's
    ``bone.matrix_local`` rotation, bones in :func:`bone_edges` order). Signs are made continuous
    over time (:func:`make_continuous`); frame 0 is the identity."""
    rest_matrices = np.asarray(rest_matrices, np.float64)
    B = len(bone_edges(parents))
    if rest_matrices.shape != (B, 3, 3):
        raise InputError(f"rest matrices have shape {rest_matrices.shape}, expected ({B}, 3, 3)")
    qw = world_rotations(parents, nodes3d)
    parent_bone = bone_parents(parents)
    qp = np.where((parent_bone >= 0)[None, :, None], qw[:, np.maximum(parent_bone, 0)],
                  np.array([1.0, 0.0, 0.0, 0.0]))
    qr = matrix_to_quat(rest_matrices)[None]                                        # (1, B, 4)
    local = quat_mul(quat_conj(qr), quat_mul(quat_mul(quat_conj(qp), qw), qr))
    local /= np.linalg.norm(local, axis=-1, keepdims=True)
    local = np.where(local[:1, :, :1] < 0, -local, local)      # frame 0 starts at w >= 0
    return make_continuous(local)


def pose_tails(parents: np.ndarray, rest_positions: np.ndarray, rest_matrices: np.ndarray,
               local: np.ndarray) -> np.ndarray:
    """Forward kinematics, the inverse of :func:`local_rotations` (for tests and previews).

    ``rest_positions (N, 3)`` metres, ``rest_matrices (B, 3, 3)``, ``local (F, B, 4)`` →
    node positions ``(F, N, 3)`` metres as Blender would pose them (rest lengths, roots fixed)."""
    return pose(parents, rest_positions, rest_matrices, local)[0]


def pose(parents: np.ndarray, rest_positions: np.ndarray, rest_matrices: np.ndarray,
         local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`pose_tails` and the bones' world rotations ``(F, B, 4)`` from rest (what carries a
    point fixed to a bone: ``head_t + q_t · (p − head_rest)``)."""
    rest_positions = np.asarray(rest_positions, np.float64)
    edges = bone_edges(parents)
    parent_bone = bone_parents(parents)
    depth = bone_depths(parent_bone)
    qr = matrix_to_quat(rest_matrices)
    F = len(local)
    qw = np.zeros((F, len(edges), 4))
    out = np.repeat(rest_positions[None], F, axis=0)
    offset = rest_positions[edges[:, 1]] - rest_positions[edges[:, 0]]
    for d in range(depth.max() + 1):
        idx = np.flatnonzero(depth == d)
        delta = quat_mul(qr[idx], quat_mul(local[:, idx], quat_conj(qr[idx])))       # R L Rᵀ
        if d == 0:
            qw[:, idx] = delta
        else:
            qw[:, idx] = quat_mul(qw[:, parent_bone[idx]], delta)
        out[:, edges[idx, 1]] = out[:, edges[idx, 0]] + quat_rotate(qw[:, idx], offset[idx])
    return out, qw


def roll_zero_quats(head: np.ndarray, tail: np.ndarray) -> np.ndarray:
    """``(B, 4)`` rest rotations of bones ``head → tail (B, 3)`` as Blender makes them for roll 0
    (Y along the bone): the smallest rotation from +Y to the bone direction (for bones pointing
    almost exactly along -Y, a 180° turn about Z)."""
    d, _ = _unit(np.asarray(tail, np.float64) - np.asarray(head, np.float64))
    q = swing(np.array([0.0, 1.0, 0.0]), d)
    q[d[:, 1] < -1 + 1e-9] = [0.0, 0.0, 0.0, 1.0]
    return q


def rest_frames(parents: np.ndarray, rest_positions: np.ndarray) -> np.ndarray:
    """Bone rest rotations ``(B, 3, 3)`` as Blender makes them for roll 0 (:func:`roll_zero_quats`).
    Without Blender (the asset stage, tests); Blender's ``bone.matrix_local`` agrees to 1e-6."""
    edges = bone_edges(parents)
    rest_positions = np.asarray(rest_positions, np.float64)
    return quat_to_matrix(roll_zero_quats(rest_positions[edges[:, 0]], rest_positions[edges[:, 1]]))


def length_drift(parents: np.ndarray, nodes3d: np.ndarray) -> float:
    """Largest change (metres) of any edge's length from frame 0: what rotation-only bones
    cannot follow."""
    edges = bone_edges(parents)
    nodes3d = np.asarray(nodes3d, np.float64)
    length = np.linalg.norm(nodes3d[:, edges[:, 1]] - nodes3d[:, edges[:, 0]], axis=-1)
    return float(np.abs(length - length[:1]).max()) if length.size else 0.0
