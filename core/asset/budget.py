"""A bone budget for game engines (issue 33): the rig cut to ``N`` bones, the motion re-fitted.

A reconstruction carries hundreds of branch bones and a bone per leaf cluster (815–1,841 joints);
an engine wants 16–128. The kept bones are the roots, the trunk (while it fits in a quarter of the
budget) and then the bones whose own turning moves the most of the tree, by the priority

    p_b = RMS_t angle(l_b(t), l̄_b) · reach_b

(``l_b`` its local rotation, ``l̄_b`` its mean, ``reach_b`` the farthest rest vertex it carries,
through its whole subtree, from its head: the displacement its turning causes there). Every other
bone — and every leaf-cluster bone — joins the group of its nearest kept ancestor, rigidly. (A
greedy choice of the bone whose tail strays farthest from its group was tried: it picks tips,
each fixing only its own vertices, and doubled the error on the broadleaf samples.)

Each kept bone's motion is then re-fitted to what the full rig plays: per frame, the rigid
transform ``W_k(t) = (R, T)`` that best carries its group's rest vertices ``p`` onto their full-rig
positions ``x(t)`` (Kabsch: ``H = Σ (p − p̄)(x − x̄)ᵀ = U S Vᵀ``, ``R = V diag(1, 1, det(V Uᵀ)) Uᵀ``,
``T = x̄ − R p̄``), on up to :data:`SAMPLES` vertices of every original bone of the group. The
reduced bones are not connected (a re-fitted bone's head may move off its parent's tail), so each
carries a location as well as a rotation: in Blender's pose-bone terms (rest matrix ``M_k``, parent
``p``) ``B_k(t) = M_k⁻¹ W_p(t)⁻¹ W_k(t) M_k``. Every vertex keeps one influence (weight 1).

:func:`budget_rig` also measures the result against the full rig on every sampled vertex and
frame (its :class:`BudgetReport`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .. import bones
from ..keys import flutter_quaternions
from ..rotations import make_continuous, matrix_to_quat, quat_conj, quat_log, quat_mul, quat_rotate
from ..tree3d import Tree3D
from .meshes import BranchMesh, LeafMesh
from .rig import BoneKeys, Rig
from .roles import TRUNK

#: rest vertices per original bone the fit and the error use (seeded sample)
SAMPLES = 24


@dataclass
class BudgetReport:
    """``bones`` kept of ``of`` (branch and leaf bones before); ``rms``, ``max`` the vertex error
    against the full rig over every sampled vertex and frame, shares of the tree's height;
    ``bone_of (of,)`` each bone's kept bone (an index into the cut rig's bones; None: every bone
    kept), which carries the vertices it carried."""

    bones: int
    of: int
    rms: float
    max: float
    bone_of: np.ndarray | None = field(default=None, compare=False)

    def line(self) -> str:
        return (f"{self.bones} bones of {self.of}: vertex error RMS {100 * self.rms:.2f} %, "
                f"max {100 * self.max:.2f} % of the height")


def world_motion(tree: Tree3D, rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """What the full rig plays: every bone's world rotation from rest ``(F, B + S, 4)`` and head
    ``(F, B + S, 3)`` metres (a point ``p`` fixed to bone ``b`` is at ``head_b + q_b (p − head_b⁰)``).
    A leaf bone turns about its own Y by its flutter (the stored model's), carried by its branch."""
    B = rig.n_branch
    nodes, qw = bones.pose(tree.parents, tree.nodes3d[0], rig.rest, rig.keys.local)
    edges = bones.bone_edges(tree.parents)
    heads = nodes[:, edges[:, 0]]
    if len(rig.names) == B:
        return qw, heads
    lv = tree.leaves
    assert lv is not None
    pb = rig.parent[B:]
    rest_q = bones.roll_zero_quats(rig.head[B:], rig.tail[B:])             # (S, 4)
    flutter = flutter_quaternions(np.asarray(lv.flutter, np.float64))     # about the bone's own Y
    local = quat_mul(rest_q[None], quat_mul(flutter, quat_conj(rest_q)[None]))      # in armature axes
    q_leaf = quat_mul(qw[:, pb], local)
    offset = rig.head[B:].astype(np.float64) - rig.head[pb].astype(np.float64)
    h_leaf = heads[:, pb] + quat_rotate(qw[:, pb], offset[None])
    return np.concatenate([qw, q_leaf], axis=1), np.concatenate([heads, h_leaf], axis=1)


def _vertex_sample(branches: BranchMesh | None, leaves: LeafMesh | None, rig: Rig,
                   seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Up to :data:`SAMPLES` rest vertices per bone (branch mesh, then leaf cards; a bone without
    vertices samples its head and tail): ``(P, 3)`` positions and ``(P,)`` their bones."""
    rng = np.random.default_rng([int(seed), 0xB0E5])
    co, bone = [], []
    if branches is not None:
        co.append(branches.co)
        bone.append(branches.bone)
    if leaves is not None:
        co.append(leaves.co)
        bone.append(leaves.bone)
    co.append(np.concatenate([rig.head, rig.tail]))                     # every bone has two points
    bone.append(np.tile(np.arange(len(rig.names)), 2))
    P = np.concatenate(co).astype(np.float64)
    b = np.concatenate(bone).astype(np.int64)
    order = np.lexsort((rng.random(len(b)), b))                          # each bone's vertices, shuffled
    b_sorted = b[order]
    start = np.searchsorted(b_sorted, b_sorted, side="left")
    rank = np.arange(len(b_sorted)) - start
    keep = order[rank < SAMPLES]
    return P[keep], b[keep]


def subtree_reach(rig: Rig, P: np.ndarray, pb: np.ndarray) -> np.ndarray:
    """``(B + S,)`` the farthest sampled rest point carried by each bone or its descendants from
    the bone's head, metres."""
    reach = np.zeros(len(rig.names))
    cur = pb.copy()
    while (cur >= 0).any():                      # up every point's chain of bones at once
        ok = cur >= 0
        np.maximum.at(reach, cur[ok], np.linalg.norm(P[ok] - rig.head[cur[ok]], axis=1))
        cur[ok] = rig.parent[cur[ok]]
    return reach


def choose_bones(rig: Rig, reach: np.ndarray, n: int) -> np.ndarray:
    """``(B + S,)`` bool: the ``n`` bones kept (module docstring): roots, the trunk while it fits in
    a quarter of ``n``, then by priority. Leaf-cluster bones are never kept."""
    total = len(rig.names)
    B = rig.n_branch
    keep = np.zeros(total, bool)
    keep[np.flatnonzero(rig.parent < 0)] = True
    trunk = np.flatnonzero(rig.role[:B] == TRUNK)
    if len(trunk) + keep.sum() <= max(1, n // 4):
        keep[trunk] = True
    local = rig.keys.local
    mean = local.mean(axis=0)
    mean /= np.maximum(np.linalg.norm(mean, axis=-1, keepdims=True), 1e-12)
    ang = np.linalg.norm(quat_log(quat_mul(quat_conj(mean)[None], local)), axis=-1)    # (F, B)
    priority = np.sqrt(np.mean(ang ** 2, axis=0)) * reach[:B]
    priority[keep[:B]] = -np.inf
    room = max(0, n - int(keep.sum()))
    best = np.argsort(-priority, kind="stable")[:room]
    keep[best[np.isfinite(priority[best])]] = True
    return keep


def groups(rig: Rig, keep: np.ndarray) -> np.ndarray:
    """``(B + S,)`` each bone's kept bone: itself when kept, else its nearest kept ancestor (root
    to tips by depth: a reconstruction's bones need not come after their parents)."""
    g = np.arange(len(rig.names))
    depth = bones.bone_depths(rig.parent)
    for d in range(1, int(depth.max()) + 1 if len(depth) else 0):
        at = np.flatnonzero((depth == d) & ~keep)
        g[at] = g[rig.parent[at]]
    return g


def kabsch(P: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rigid transforms ``(F, 3, 3)``, ``(F, 3)`` that best carry ``P (n, 3)`` onto ``X (F, n,
    3)`` in least squares (module docstring; reflections excluded)."""
    pc = P.mean(axis=0)
    xc = X.mean(axis=1)
    H = np.einsum("ni,fnj->fij", P - pc, X - xc[:, None])
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.einsum("fji,fkj->fik", Vt, U)))
    D = np.zeros_like(H)
    D[:, 0, 0], D[:, 1, 1], D[:, 2, 2] = 1.0, 1.0, np.where(d == 0, 1.0, d)
    R = np.einsum("fji,fjk,flk->fil", Vt, D, U)
    return R, xc - np.einsum("fij,j->fi", R, pc)


def budget_rig(tree: Tree3D, rig: Rig, branches: BranchMesh | None, leaves: LeafMesh | None,
               n: int) -> tuple[Rig, BranchMesh | None, LeafMesh | None, BudgetReport]:
    """``rig`` cut to at most ``n`` bones with the motion re-fitted, the meshes' vertices moved to
    their kept bones, and the error against the full rig (module docstring). ``n`` ≥ the rig's
    bones: the rig as it is (its error 0)."""
    total = len(rig.names)
    if n >= total:
        return rig, branches, leaves, BudgetReport(total, total, 0.0, 0.0)
    qw, heads = world_motion(tree, rig)
    P, pb = _vertex_sample(branches, leaves, rig, int((tree.meta.get("mesh") or {}).get("seed", 0)))
    head0 = rig.head.astype(np.float64)
    X = heads[:, pb] + quat_rotate(qw[:, pb], P[None] - head0[pb][None])      # (F, P, 3) the full rig
    keep = choose_bones(rig, subtree_reach(rig, P, pb), n)
    g = groups(rig, keep)
    kept = np.flatnonzero(keep)
    index = np.full(total, -1)
    index[kept] = np.arange(len(kept))
    F = len(qw)
    R = np.empty((F, len(kept), 3, 3))
    T = np.empty((F, len(kept), 3))
    owner = g[pb]
    for j, k in enumerate(kept):                 # one least-squares fit per kept bone (≤ a few hundred)
        sel = owner == k
        R[:, j], T[:, j] = kabsch(P[sel], X[:, sel])
    fitted = np.einsum("fnij,nj->fni", R[:, index[owner]], P) + T[:, index[owner]]
    err = np.linalg.norm(fitted - X, axis=-1)
    H = max(float(np.ptp(tree.nodes3d[0][:, 2])), 1e-9)
    remap = index[g]
    report = BudgetReport(len(kept), total, float(np.sqrt(np.mean(err ** 2)) / H), float(err.max() / H), remap)
    small = _reduced_rig(rig, kept, g, R, T)
    new_branches = None if branches is None else replace(branches, bone=remap[branches.bone].astype(np.int32))
    new_leaves = None if leaves is None else replace(leaves, bone=remap[leaves.bone].astype(np.int32))
    return small, new_branches, new_leaves, report


def _rest_matrices(rig: Rig, kept: np.ndarray) -> np.ndarray:
    """``(K, 4, 4)`` the kept bones' rest matrices in armature space (Blender's ``matrix_local``;
    only branch bones are ever kept)."""
    M = np.tile(np.eye(4), (len(kept), 1, 1))
    M[:, :3, :3] = rig.rest[kept]
    M[:, :3, 3] = rig.head[kept]
    return M


def _reduced_rig(rig: Rig, kept: np.ndarray, g: np.ndarray, R: np.ndarray, T: np.ndarray) -> Rig:
    """The kept bones as a :class:`Rig` whose keys carry rotation and location per frame: ``B_k(t)
    = M_k⁻¹ W_p(t)⁻¹ W_k(t) M_k`` (module docstring)."""
    F, K = R.shape[:2]
    index = np.full(len(rig.names), -1)
    index[kept] = np.arange(K)
    up = rig.parent[kept]
    parent = np.where(up >= 0, index[g[np.maximum(up, 0)]], -1).astype(np.int32)
    W = np.tile(np.eye(4), (F, K, 1, 1))
    W[..., :3, :3], W[..., :3, 3] = R, T
    M = _rest_matrices(rig, kept)
    Wp = np.where((parent >= 0)[None, :, None, None], W[:, np.maximum(parent, 0)], np.eye(4))
    Bk = np.linalg.inv(M)[None] @ np.linalg.inv(Wp) @ W @ M[None]
    local = matrix_to_quat(Bk[..., :3, :3])
    local = make_continuous(local)
    keys = BoneKeys(local, rig.keys.frames, None, np.zeros(K, bool), location=Bk[..., :3, 3])
    rest = M[:, :3, :3]
    return Rig([rig.names[k] for k in kept], parent, rig.head[kept], rig.tail[kept], np.zeros(K, bool),
               rig.role[kept], rest, keys, None, rig.fps, None)
