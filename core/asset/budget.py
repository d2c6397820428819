"""A bone budget for game engines (issue 33): the rig cut to ``N`` bones, the motion re-fitted.

A reconstruction carries hundreds of branch bones and a bone per leaf cluster (815–1,841 joints);
an engine wants 16–128. The kept bones are the roots and the trunk (while it fits in a quarter of
the budget); every other bone — and every leaf-cluster bone — joins the group of its nearest kept
ancestor and moves rigidly with it. The rest of the budget is spent greedily: each step keeps the
branch bone whose split of its group (its subtree in the group against the rest) lowers the
groups' summed squared error the most, the error a rigid fit leaves in closed form
(:func:`rigid_sse`), so a conifer's leader, whose bones each turn little but together carry
two-thirds of the crown, is cut before its side branches. (The first choice ranked bones by their
own turning × reach: it left a conifer's whole upper crown in one rigid group, 6.3 % of the height
off at 64 bones where the greedy split leaves 3.2 %; ranking by how far a bone's tail strays from
its group picked tips, each fixing only its own vertices.)

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
from scipy import sparse

from .. import bones
from ..keys import flutter_quaternions
from ..rotations import make_continuous, matrix_to_quat, quat_conj, quat_mul, quat_rotate
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


def _fit_stats(P: np.ndarray, X: np.ndarray, pb: np.ndarray, nb: int) -> tuple[np.ndarray, np.ndarray]:
    """Each bone's additive sums of its sampled points for a rigid fit: ``(nb, 5)`` [n, Σp (3),
    Σ|p|²] and ``(nb, F, 13)`` [Σx (3), Σ|x|², Σ p xᵀ (9)] per frame (``P (N, 3)`` rest, ``X (F, N,
    3)`` posed, ``pb (N,)`` their bones)."""
    F, N = X.shape[:2]
    static = np.zeros((nb, 5))
    static[:, 0] = np.bincount(pb, minlength=nb)
    for i in range(3):
        static[:, 1 + i] = np.bincount(pb, P[:, i], minlength=nb)
    static[:, 4] = np.bincount(pb, (P ** 2).sum(axis=1), minlength=nb)
    per = np.zeros((nb, F, 13))
    ones = sparse.csr_matrix((np.ones(N), (pb, np.arange(N))), shape=(nb, N))
    Xt = X.transpose(1, 0, 2).reshape(N, F * 3)                           # (N, F·3)
    per[..., 0:3] = (ones @ Xt).reshape(nb, F, 3)
    per[..., 3] = ones @ (X ** 2).sum(axis=-1).T
    for i in range(3):                                                   # Σ p_i x_j: one sparse product per i
        w = sparse.csr_matrix((P[:, i], (pb, np.arange(N))), shape=(nb, N))
        per[..., 4 + 3 * i:7 + 3 * i] = (w @ Xt).reshape(nb, F, 3)
    return static, per


def rigid_sse(static: np.ndarray, per: np.ndarray) -> np.ndarray:
    """``(...)`` the squared error, summed over points and frames, that the best rigid motion of a
    point set leaves, from its sums (:func:`_fit_stats`; ``static (..., 5)``, ``per (..., F, 13)``).
    With ``H = Σ (p − p̄)(x − x̄)ᵀ`` and its singular values ``σ``, per frame

        min_R,T Σ |R p + T − x|² = Σ|x − x̄|² + Σ|p − p̄|² − 2 (σ₁ + σ₂ + sign(det H) σ₃)

    (Kabsch: the best rotation reaches ``tr(R H) = σ₁ + σ₂ ± σ₃``, the sign keeping it a rotation)."""
    n = np.maximum(static[..., 0], 1e-12)
    sp, spp = static[..., 1:4], static[..., 4]
    sx, sxx = per[..., 0:3], per[..., 3]
    H = per[..., 4:].reshape(per.shape[:-1] + (3, 3)) - sp[..., None, :, None] * sx[..., None, :] / n[..., None, None, None]
    sv = np.sqrt(np.maximum(np.linalg.eigvalsh(np.swapaxes(H, -1, -2) @ H), 0.0))    # ascending
    sign = np.where(np.linalg.det(H) < 0, -1.0, 1.0)
    best = sv[..., 2] + sv[..., 1] + sign * sv[..., 0]
    spread = sxx - (sx ** 2).sum(axis=-1) / n[..., None] + (spp - (sp ** 2).sum(axis=-1) / n)[..., None]
    return np.maximum(spread - 2.0 * best, 0.0).sum(axis=-1)


def choose_bones(rig: Rig, P: np.ndarray, pb: np.ndarray, X: np.ndarray, n: int) -> np.ndarray:
    """``(B + S,)`` bool: the ``n`` bones kept (module docstring): roots, the trunk while it fits in
    a quarter of ``n``, then the greedy splits. Leaf-cluster bones are never kept. ``P``, ``pb``,
    ``X`` the sampled rest points, their bones and their full-rig positions ``(F, N, 3)``."""
    total = len(rig.names)
    B = rig.n_branch
    keep = np.zeros(total, bool)
    keep[np.flatnonzero(rig.parent < 0)] = True
    trunk = np.flatnonzero(rig.role[:B] == TRUNK)
    if len(trunk) + keep.sum() <= max(1, n // 4):
        keep[trunk] = True
    centre = P.mean(axis=0)
    static, per = _fit_stats(P - centre, X - centre, pb, total)
    depth = bones.bone_depths(rig.parent)
    for d in range(int(depth.max()) if total else 0, 0, -1):     # sums over each bone's part of its group
        at = np.flatnonzero((depth == d) & ~keep)
        np.add.at(static, rig.parent[at], static[at])
        np.add.at(per, rig.parent[at], per[at])
    gain = np.full(total, -np.inf)
    g = groups(rig, keep)
    dirty = np.ones(total, bool)
    while keep.sum() < n:
        cand = np.flatnonzero(dirty & ~keep & (np.arange(total) < B))
        if len(cand):
            root = g[cand]
            whole = rigid_sse(static[root], per[root])
            split = rigid_sse(static[cand], per[cand]) + rigid_sse(static[root] - static[cand], per[root] - per[cand])
            gain[cand] = whole - split
        gain[keep] = -np.inf
        c = int(np.argmax(gain))
        if not np.isfinite(gain[c]):
            break
        keep[c] = True
        a = rig.parent[c]
        while a >= 0:                            # its group's bones above it no longer carry it
            static[a] -= static[c]
            per[a] -= per[c]
            if keep[a]:
                break
            a = rig.parent[a]
        old = g[c]
        g = groups(rig, keep)
        dirty = (g == old) | (g == c)
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
    keep = choose_bones(rig, P, pb, X, n)
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
