"""The tree's rig as any writer copies it (issue 33): bones, rest pose and the keys of the motion,
in typed arrays (Blender's armature builder, and the engine exports to come, read these; nothing
here needs bpy).

Bones: one per edge of the tree, named after its child node (``B###``, :func:`core.bones.
bone_names`), connected to its parent bone; then one per leaf cluster (``L0000``…), head at the
cluster's centre, tail along its main axis, parented (not connected) to the bone of the cluster's
node. Rest rotations are Blender's roll-0 frames (:func:`core.bones.rest_frames`: Y along the bone).
The branch bones' pose is a quaternion per frame relative to the rest (:func:`core.bones.
local_rotations`), kept where the motion needs it (:func:`core.keys.tree_keys`); a leaf bone turns
about its own Y by its flutter angle (W and Y channels only), one steady cycle where it can be.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import bones, keys
from ..keys import TreeKeys
from ..tree3d import Tree3D, key_frames
from .roles import LEAF_CLUSTER, node_roles


@dataclass
class BoneKeys:
    """The branch bones' keys. ``local (F, B, 4)`` quaternions (w, x, y, z) at scene ``frames
    (F,)`` (1-based, subframes for a variable frame rate); ``keep (F, B)`` bool the frames kept as
    Bezier keys (None: a LINEAR key on every frame); ``sampled (B,)`` bool bones stored as baked
    samples on every frame instead (only for evenly timed clips); ``left``, ``right`` ``(F, B, 4)``
    the Bezier handles' values at a third of the span (None without ``keep``); ``location (F, B,
    3)`` metres each bone's pose location in its rest frame, keyed on every frame (a bone budget's
    re-fitted bones, :mod:`.budget`; None: the bones only turn)."""

    local: np.ndarray
    frames: np.ndarray
    keep: np.ndarray | None
    sampled: np.ndarray
    left: np.ndarray | None = None
    right: np.ndarray | None = None
    location: np.ndarray | None = None


@dataclass
class LeafKeys:
    """The leaf bones' flutter keys, LINEAR: ``q (K, S, 4)`` quaternions at scene ``frames (K,)``,
    only the rows of ``keep (K, S)`` per bone (None: all); ``cyclic`` one period repeated (a
    *Cycles* modifier, an engine's loop)."""

    q: np.ndarray
    frames: np.ndarray
    keep: np.ndarray | None
    cyclic: bool


@dataclass
class Rig:
    """``names`` (B branch bones, then S leaf bones); ``parent (B+S,)`` int32 parent bone (-1: the
    root bone); ``head``, ``tail (B+S, 3)`` float32 metres at rest; ``connected (B+S,)`` bool;
    ``role (B+S,)`` int8 (:mod:`.roles`; a branch bone has its child node's); ``rest (B, 3, 3)``
    the branch bones' rest rotations; ``keys`` the branch bones' :class:`BoneKeys`, ``leaf_keys``
    the leaf bones' :class:`LeafKeys` (None without leaves); ``fps``; ``reduced`` the kept keys'
    record (:class:`core.TreeKeys`, None with every key)."""

    names: list[str]
    parent: np.ndarray
    head: np.ndarray
    tail: np.ndarray
    connected: np.ndarray
    role: np.ndarray
    rest: np.ndarray
    keys: BoneKeys
    leaf_keys: LeafKeys | None
    fps: float
    reduced: TreeKeys | None = None

    @property
    def n_branch(self) -> int:
        return len(self.rest)

    @property
    def leaf_names(self) -> list[str]:
        return self.names[self.n_branch:]


def leaf_bone_names(count: int) -> list[str]:
    return [f"L{k:04d}" for k in range(count)]


def leaf_bones(tree: Tree3D) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """The leaf clusters' bones: names, parent branch bone ``(S,)``, head and tail ``(S, 3)``."""
    lv = tree.leaves
    assert lv is not None
    names = leaf_bone_names(lv.count)
    bone_of = np.full(tree.n_nodes, -1)
    bone_of[bones.bone_edges(tree.parents)[:, 1]] = np.arange(tree.n_nodes - 1)
    parent = bone_of[np.asarray(lv.node, np.int64)]
    if (parent < 0).any():
        missing = sorted(set(int(n) for n in np.asarray(lv.node)[parent < 0]))
        raise RuntimeError(f"leaf clusters sit on nodes without a bone: {missing[:5]}")
    head = lv.pos.astype(np.float32)
    tail = head + lv.axis.astype(np.float32) * np.float32(max(lv.radius, 1e-4))
    return names, parent.astype(np.int32), head, tail


def bone_keys(local: np.ndarray, frames: np.ndarray, keep: np.ndarray | None) -> BoneKeys:
    """How the branch bones are keyed: every frame LINEAR (``keep`` None), else baked samples for
    bones keeping every frame of an evenly timed clip and Bezier keys with
    :func:`core.keys.handles` for the others."""
    frames = np.asarray(frames, np.float32)
    even = bool(np.all(np.diff(frames) == 1.0)) and float(frames[0]).is_integer()
    if keep is None:
        return BoneKeys(local, frames, None, np.zeros(local.shape[1], bool))
    left, right = keys.handles(local, keep, frames)
    return BoneKeys(local, frames, keep, keep.all(axis=0) & even, left, right)


def leaf_keys(tree: Tree3D, frames: np.ndarray, reduced: TreeKeys | None) -> LeafKeys:
    """The flutter keys: one period of each cluster's steady flutter from the first frame (the
    reduction found one), else the kept frames (every frame with ``reduced`` None)."""
    frames = np.asarray(frames, np.float32)
    assert tree.leaves is not None
    if reduced is not None and reduced.cycle is not None:
        cycle = reduced.cycle
        return LeafKeys(keys.flutter_quaternions(cycle.angles), (frames[0] + cycle.frames).astype(np.float32),
                        None, True)
    return LeafKeys(keys.flutter_quaternions(tree.leaves.flutter), frames,
                    None if reduced is None else reduced.leaves, False)


def tree_rig(tree: Tree3D, every_key: bool = False, leaves: bool = True) -> Rig:
    """The :class:`Rig` of ``tree``: its bones (and, with ``leaves`` and leaf clusters, theirs) and
    its keys, reduced within :data:`core.keys.KEY_TOLERANCE` of the height unless ``every_key``."""
    edges = bones.bone_edges(tree.parents)
    rest_pos = np.asarray(tree.nodes3d[0], np.float32)
    rest = bones.rest_frames(tree.parents, tree.nodes3d[0])
    local = bones.local_rotations(tree.parents, tree.nodes3d, rest)
    frames = key_frames(tree)
    reduced = None if every_key else keys.tree_keys(tree, rest, frames, local=local)
    names = bones.bone_names(tree.parents)
    parent = bones.bone_parents(tree.parents).astype(np.int32)
    head, tail = rest_pos[edges[:, 0]], rest_pos[edges[:, 1]]
    role = node_roles(tree)[edges[:, 1]]
    connected = parent >= 0
    with_leaves = leaves and tree.leaves is not None and tree.leaves.count > 0
    lkeys = None
    if with_leaves:
        lnames, lparent, lhead, ltail = leaf_bones(tree)
        names = names + lnames
        parent = np.concatenate([parent, lparent])
        head, tail = np.concatenate([head, lhead]), np.concatenate([tail, ltail])
        role = np.concatenate([role, np.full(len(lnames), LEAF_CLUSTER, np.int8)])
        connected = np.concatenate([connected, np.zeros(len(lnames), bool)])
        lkeys = leaf_keys(tree, frames, reduced)
    return Rig(names, parent, head.astype(np.float32), tail.astype(np.float32), connected, role, rest,
               bone_keys(local, frames, None if reduced is None else reduced.bones), lkeys, float(tree.fps),
               reduced)
