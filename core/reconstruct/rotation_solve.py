"""One frame of the probabilistic motion solve (:mod:`.motion`): every node's rotation at once, as
one sparse least-squares problem.

Unknowns, per non-root node k: its rotation step ω_k (radians, world axes, turning its subtree
about its parent joint p). A node's position moves by the rotations of every node on its path,

    δx_j = Σ_{i ∈ path(j)} ω_i × (x_j − x_p(i))                                   (linearized)

so the track term couples each node with all its ancestors (a dense block per ancestor pair,
Σ depth blocks: 4500 for 185 nodes 36 deep; its Cholesky factor costs Σ depth² block products).
Here the same problem is written with two unknowns per node that only meet their parent's:

    Ω_k = Σ_{i ∈ path(k)} ω_i          the turn of edge p→k this frame  (ω_k = Ω_k − Ω_p)
    δx_k = δx_p + Ω_k × e_k            its end's move, e_k = x_k − x_p            (held by a penalty
                                       μ |δx_k − δx_p + [e_k]× Ω_k|², μ = 10⁶ / σ_track²)

Every term of the posterior is then a function of one node or of one node and its parent:

    track   ½ c_k/σ_track² |K(x_k + δx_k) − x'_k|²                  (K: x and z rows)
    depth   ½ Σ_{j ∈ sub(k)} ((ω_k × (x_j − x_p))_y)² / σ_depth²    (depth steps ω_k causes)
    shape   ½ (α_k − α_k(1) − ω_k · ∂α/∂ω)² / σ_shape(d_k)²          ∂α/∂ω = −(u × w) / sin α
    prior   ½ |ω_k|² / σ_prior²,   rest ½ |A_k + ω_k|² / σ_rest²

so the normal equations are a symmetric positive definite matrix with the tree's sparsity: 5×5
blocks (δx's x and z, Ω: nothing reads δx's depth) on the diagonal and between each node and its
parent. Ordered leaves first its LU factor has no fill-in (eliminating a node touches only its
parent), one SuperLU call of ~0.4 ms for 185 nodes. The subtree sums of the depth term come from
one sparse product with the subtree matrix. Measured on the broad sample (185 nodes, 36 deep):
the level-by-level solve it replaces took 13 ms a frame, this one 1.5 ms, with the same
reprojection (median 0.13 % of the height against 0.19 %) and branch lengths exact (every edge is
turned by a rotation matrix, never stretched).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..rotations import rodrigues
from ..topology import node_depths, topological_order

BLOCK = 5           # unknowns per node: δx's x and z, Ω
PENALTY = 1e6        # μ σ_track²: δx_k − δx_p = Ω_k × e_k holds to ~1e-6 of a track σ


def cross_matrix(a: np.ndarray) -> np.ndarray:
    """``[a]×`` ``(..., 3, 3)`` for ``a (..., 3)``: ``[a]× b = a × b``."""
    K = np.zeros(a.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -a[..., 2], a[..., 1]
    K[..., 1, 0], K[..., 1, 2] = a[..., 2], -a[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -a[..., 1], a[..., 0]
    return K


@dataclass
class TreeSystem:
    """What stays fixed for a skeleton ``parents (N,)``: the non-root ``nodes (n,)`` leaves first,
    their ``par (n,)`` and its place ``ppos (n,)`` in ``nodes`` (−1: a root), ``kid`` the
    ``nodes`` positions whose parent is not a root; sparse sums ``path (N, N)`` (over a node's
    path, roots excluded), ``subtree (N, N)`` (over its subtree, itself included) and
    ``children (n, n)`` (over its children), ``n_kids (n,)``; ``root (N,)`` each node's root; the normal
    equations' CSC pattern (``indices``, ``indptr``, and ``order`` taking the blocks' entries to it).
    """

    nodes: np.ndarray
    par: np.ndarray
    ppos: np.ndarray
    kid: np.ndarray
    path: sp.csr_matrix
    subtree: sp.csr_matrix
    children: sp.csr_matrix
    n_kids: np.ndarray
    root: np.ndarray
    indices: np.ndarray
    indptr: np.ndarray
    order: np.ndarray

    @classmethod
    def of(cls, parents: np.ndarray) -> TreeSystem:
        parents = np.asarray(parents)
        N = len(parents)
        topo = topological_order(parents)
        nodes = topo[parents[topo] >= 0][::-1]
        n = len(nodes)
        pos = np.full(N, -1)
        pos[nodes] = np.arange(n)
        par = parents[nodes]
        ppos = pos[par]
        kid = np.flatnonzero(ppos >= 0)
        depth = node_depths(parents)
        root = np.arange(N)                              # each node's root, root first
        for v in topo:
            if parents[v] >= 0:
                root[v] = root[parents[v]]
        # path sums: row j has a one at every non-root node of j's path (j included)
        rows = np.repeat(np.arange(N), depth)
        cols = np.empty(len(rows), int)
        cur = np.arange(N)
        filled = np.zeros(N, int)
        start = np.concatenate([[0], np.cumsum(depth)[:-1]])
        for _ in range(int(depth.max(initial=0))):
            live = depth > filled
            cols[start[live] + filled[live]] = cur[live]
            cur = np.where(live, parents[cur], cur)
            filled += live
        path = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(N, N))
        children = sp.csr_matrix((np.ones(len(kid)), (ppos[kid], kid)), shape=(n, n))
        # blocks: (k, k) for every node, (k, p) and (p, k) for every non-root parent
        B = BLOCK
        bi = np.concatenate([np.arange(n), kid, ppos[kid]])
        bk = np.concatenate([np.arange(n), ppos[kid], kid])
        r = np.broadcast_to(B * bi[:, None, None] + np.arange(B)[None, :, None], (len(bi), B, B)).ravel()
        c = np.broadcast_to(B * bk[:, None, None] + np.arange(B)[None, None, :], (len(bi), B, B)).ravel()
        order = np.argsort(c * (B * n) + r, kind="stable")
        indptr = np.searchsorted(c[order], np.arange(B * n + 1)).astype(np.int32)
        return cls(nodes, par, ppos, kid, path, path.T.tocsr(), children, np.bincount(ppos[kid], minlength=n), root,
                   r[order].astype(np.int32), indptr, order)

    @property
    def size(self) -> int:
        return BLOCK * len(self.nodes)


@dataclass
class FrameTerms:
    """The frame's fixed weights: ``track (n,)`` c_k / σ_track² per node (1/px²) and the node's
    2D target ``target (n, 2)`` (x, z) px; the scalars of the other terms."""

    track: np.ndarray
    target: np.ndarray
    inv_depth: float          # 1 / σ_depth² (1/px²)
    sigma_shape: np.ndarray   # (n,) radians
    alpha1: np.ndarray        # (n,) frame-1 branch angles, radians
    prior: float              # 1 / σ_prior²
    rest: float               # 1 / σ_rest²
    penalty: float            # μ = PENALTY / σ_track² (1/px²)


def branch_angles(X: np.ndarray, sys_: TreeSystem, grand: np.ndarray):
    """Unit branch directions ``u (n, 3)``, parent directions ``w (n, 3)`` (the vertical where
    the parent is a root) and the angles between them ``(n,)`` radians."""
    par = sys_.par
    u = X[sys_.nodes] - X[par]
    u /= np.maximum(np.linalg.norm(u, axis=1), 1e-12)[:, None]
    d = np.where((grand >= 0)[:, None], X[par] - X[np.maximum(grand, 0)], [0.0, 0.0, 1.0])
    w = d / np.maximum(np.linalg.norm(d, axis=1), 1e-12)[:, None]
    return u, w, np.arccos(np.clip(np.sum(u * w, 1), -1, 1))


def gauss_newton_step(X: np.ndarray, wf: np.ndarray, A0: np.ndarray, sys_: TreeSystem,
                      grand: np.ndarray, terms: FrameTerms) -> tuple[np.ndarray, np.ndarray]:
    """The step ``(n, 3)`` of every node's rotation ω (radians) from positions ``X (N, 3)`` px,
    with ``wf (n, 3)`` this frame's rotations so far and ``A0 (n, 3)`` those of earlier frames;
    and the move of the nodes' (x, z) it predicts, ``(n, 2)`` px (to first order)."""
    nodes, par, kid, pp = sys_.nodes, sys_.par, sys_.kid, sys_.ppos[sys_.kid]
    n = len(nodes)
    # depth term: Σ_{j ∈ sub(k)} r rᵀ with r = (b_z, 0, −b_x), b = x_j − x_p — from subtree moments
    xx, xz = X[:, 0], X[:, 2]
    m = (sys_.subtree @ np.stack([np.ones(len(X)), xx, xz, xx * xx, xz * xz, xx * xz], 1))[nodes]
    q = X[par]
    qx, qz = q[:, 0], q[:, 2]
    szz = m[:, 4] - 2 * qz * m[:, 2] + m[:, 0] * qz * qz
    sxx = m[:, 3] - 2 * qx * m[:, 1] + m[:, 0] * qx * qx
    sxz = m[:, 5] - qx * m[:, 2] - qz * m[:, 1] + m[:, 0] * qx * qz
    Q = np.zeros((n, 3, 3))
    Q[:, 0, 0], Q[:, 2, 2] = szz * terms.inv_depth, sxx * terms.inv_depth
    Q[:, 0, 2] = Q[:, 2, 0] = -sxz * terms.inv_depth
    gq = np.einsum("nij,nj->ni", Q, wf)
    # shape term, linearized: α(ω) ≈ α − ω · (u × w) / sin α
    u, w, alpha = branch_angles(X, sys_, grand)
    sin = np.maximum(np.sin(alpha), 1e-3)
    gs = -np.cross(u, w) / (sin * terms.sigma_shape)[:, None]
    Q += gs[:, :, None] * gs[:, None, :]
    Q[:, [0, 1, 2], [0, 1, 2]] += terms.prior + terms.rest
    gq += gs * ((alpha - terms.alpha1) / terms.sigma_shape)[:, None] + terms.prior * wf + terms.rest * (A0 + wf)
    # penalty rows K(δx_k − δx_p + C_k Ω_k), C_k = [e_k]× (only x and z: nothing reads δx's depth)
    mu = terms.penalty
    KC = cross_matrix(X[nodes] - q)[:, [0, 2], :]                  # (n, 2, 3)
    g = np.zeros((n, BLOCK))
    g[:, :2] = terms.track[:, None] * (X[nodes][:, [0, 2]] - terms.target)
    g[:, 2:] = gq - sys_.children @ gq
    Qc = (sys_.children @ Q.reshape(n, 9)).reshape(n, 3, 3)  # Σ over children of their Q
    D = np.zeros((n, BLOCK, BLOCK))
    D[:, [0, 1], [0, 1]] = (mu * (1.0 + sys_.n_kids) + terms.track)[:, None]
    D[:, :2, 2:] = mu * KC
    D[:, 2:, :2] = mu * KC.transpose(0, 2, 1)
    D[:, 2:, 2:] = mu * np.einsum("nki,nkj->nij", KC, KC) + Q + Qc
    O = np.zeros((len(kid), BLOCK, BLOCK))                     # block (k, p)
    O[:, [0, 1], [0, 1]] = -mu
    O[:, 2:, :2] = -mu * KC[kid].transpose(0, 2, 1)
    O[:, 2:, 2:] = -Q[kid]
    data = np.concatenate([D.ravel(), O.ravel(), O.transpose(0, 2, 1).ravel()])[sys_.order]
    H = sp.csc_matrix((data, sys_.indices, sys_.indptr), shape=(sys_.size, sys_.size))
    lu = splu(H, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True, "Equil": False})
    z = -lu.solve(g.ravel()).reshape(n, BLOCK)
    step = z[:, 2:].copy()
    step[kid] -= z[pp, 2:]                                         # ω_k = Ω_k − Ω_p
    return step, z[:, :2]


def turn(X: np.ndarray, dw: np.ndarray, sys_: TreeSystem) -> np.ndarray:
    """Positions ``(N, 3)`` after turning every node's subtree by ``dw (N, 3)`` (radians, zero at
    the roots): each edge turns by the sum of its path's rotations (first order in the
    composition, exact in length), positions are the sums of the turned edges from the root."""
    e = np.zeros_like(X)
    e[sys_.nodes] = X[sys_.nodes] - X[sys_.par]
    R = rodrigues(sys_.path @ dw)
    return X[sys_.root] + sys_.path @ np.einsum("nij,nj->ni", R, e)
