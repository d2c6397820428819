"""Stage 7 — 3D motion from the moving 2D skeleton (paper §4).

Every node i rotates its subtree about its parent joint p by a small rotation r_i(t) per frame
(a rotation vector ω, world axes). Frame by frame, root to leaf — all nodes of one depth at once,
their subtrees being disjoint — the probabilistic solver maximizes

    p(r_i(t)) ∝ exp(−Σ_{j ∈ subtree(i)} |K x_j(t) − x'_j(t)|² / 2σ_track²)     track term
              · exp(−(α_i(t) − α_i(1))² / 2σ_shape(d_i)²)                    shape term
              · U(ω; [−δ_r, δ_r]³)                                          per-frame prior
              · [|Σ_τ r_i(τ)| ≤ Δ]                                          accumulated bound

where each subtree node's track term is weighted by its 2D motion confidence c_j(t) (what the
tracks measured there, :mod:`.node_motion`; floored at 0.05): a node moved by a guess pulls little.

with K the orthographic projection along depth (x, z), x' the tracked 2D position, α the angle
between the branch and its parent branch, σ_shape growing with the branching level d_i. Instead
of a grid search it takes a few Gauss–Newton steps on the linearized track and shape terms
(R(ω)v ≈ v + ω × v) with a weak Gaussian on ω that fixes the otherwise free twist, then clips ω to
the prior's box and to the Δ ball. Two terms the paper does not have keep what a single camera
cannot see from drifting (measured on synthetic trees, without them the accumulated rotations ran
into Δ and tips swung 3× the true depth): a Gaussian on each subtree node's per-frame depth step
and a weak pull of the accumulated rotation back to rest. Branch lengths stay exact (only
rotations are applied).

The deterministic baseline places each node where the sphere about its parent joint (radius the
branch length) meets the line of sight through its tracked 2D position, taking the intersection
nearer its previous depth; with no intersection the target is pulled toward the previous
projection until there is one.

All coordinates are pixels of frame 1 in the lift's plane frame (x right, y depth, z up, origin
at the trunk base).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import param
from ..progress import ProgressFn, report
from ..rotations import rodrigues
from ..topology import chains, children_lists, topological_order

SOLVERS = ("probabilistic", "deterministic")

@dataclass
class MotionParams:
    """σ and bounds of the probabilistic solver (lengths as shares of the tree height, angles in
    radians). ``solver`` is "probabilistic" (default) or "deterministic"."""

    solver: str = param("probabilistic", choices=SOLVERS, what="solver")
    sigma_track: float = 0.0075         # of the tree height
    sigma_shape: float = 0.02         # radians at level 0 …
    sigma_shape_growth: float = 0.5   # … times (1 + growth · level)
    max_step: float = 0.15            # δ_r: per-frame rotation bound per axis
    max_total: float = np.pi / 4      # Δ: bound of the accumulated rotation
    depth_sigma: float = 0.01         # per-frame depth step of subtree nodes (share of the height):
                                      # what the camera cannot see should not swing freely
    rest_sigma: float = 0.15          # radians: weak pull of the accumulated rotation back to rest
    prior_sigma: float = 0.5          # weak Gaussian on ω (fixes the free twist), radians
    iterations: int = 2


@dataclass
class Motion:
    """``nodes (F, N, 3)`` px per frame; ``accumulated (F, N, 3)`` Σ ω per node (radians)."""

    nodes: np.ndarray
    accumulated: np.ndarray


@dataclass
class _Levels:
    """Per tree depth: nodes, their parents, and (node-slot, member) pairs of their subtrees."""

    nodes: list
    parents: list
    slot: list
    member: list
    grand: list   # parent of the parent (−1: use the vertical)


def _levels(parents: np.ndarray) -> _Levels:
    ch = children_lists(parents)
    order = topological_order(parents)
    depth = np.zeros(len(parents), int)
    for n in order:
        if parents[n] >= 0:
            depth[n] = depth[parents[n]] + 1
    sub: dict = {}
    for n in order[::-1]:
        sub[n] = np.concatenate([[n]] + [sub[c] for c in ch[n]]).astype(int) if ch[n] else np.array([n])
    lv = _Levels([], [], [], [], [])
    for d in range(1, int(depth.max()) + 1 if len(parents) else 1):
        nodes = np.flatnonzero(depth == d)
        lv.nodes.append(nodes)
        lv.parents.append(parents[nodes])
        lv.grand.append(parents[parents[nodes]])
        lv.slot.append(np.concatenate([np.full(len(sub[n]), k) for k, n in enumerate(nodes)]))
        lv.member.append(np.concatenate([sub[n] for n in nodes]))
    return lv


def branch_angle(x: np.ndarray, p: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Angle (radians) between branches p→x and g→p, for rows of ``(B, 3)`` positions."""
    a = x - p
    b = p - g
    cos = np.sum(a * b, 1) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-12)
    return np.arccos(np.clip(cos, -1, 1))


def _parent_dirs(X: np.ndarray, par: np.ndarray, grand: np.ndarray) -> np.ndarray:
    """Unit parent-branch directions (vertical where there is no grandparent)."""
    d = np.where((grand >= 0)[:, None], X[par] - X[np.maximum(grand, 0)], [0.0, 0.0, 1.0])
    return d / np.maximum(np.linalg.norm(d, axis=1), 1e-12)[:, None]


def smooth_chain_targets(targets: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Tracked positions ``(F, N, 2)`` with every chain node (exactly one child, not the root)
    moved by interpolating the displacements of the chain's two end nodes (branch points, tips or
    the root) by arc length. Each 2D node follows its own nearby tracks, so a chain's edges
    stretch and shrink with tracker noise; a 3D branch of fixed length cannot follow stretching and
    turns compression into spurious swings in depth."""
    N = len(parents)
    n_kids = np.bincount(parents[parents >= 0], minlength=N)
    anchor = (n_kids != 1) | (parents < 0)
    p0 = targets[0]
    cs = chains(parents, p0, anchor)
    chain = np.flatnonzero(~anchor)
    if len(chain) == 0:
        return targets.copy()
    a, b = cs.up[chain], cs.down[chain]
    s = cs.fraction(chain)
    disp = targets - targets[:1]
    out = targets.copy()
    out[:, chain] = p0[chain] + (1 - s)[None, :, None] * disp[:, a] + s[None, :, None] * disp[:, b]
    return out


def solve_motion(rest: np.ndarray, parents: np.ndarray, level: np.ndarray, targets: np.ndarray,
                 params: MotionParams | None = None, progress: ProgressFn | None = None,
                 confidence: np.ndarray | None = None) -> Motion:
    """3D node positions for every frame.

    ``rest (N, 3)`` frame-1 3D skeleton (px, plane frame), ``parents (N,)``, ``level (N,)``
    branching order, ``targets (F, N, 2)`` tracked positions projected into the plane as (x, z) px
    (chain nodes' targets are first smoothed, :func:`smooth_chain_targets`), ``confidence (F, N)``
    the targets' motion confidence (None: all 1). Frame 1 is ``rest``.
    """
    params = params or MotionParams()
    if params.solver not in SOLVERS:
        from ..errors import InputError
        raise InputError(f"unknown motion solver '{params.solver}'; use probabilistic or deterministic")
    F, N = targets.shape[:2]
    targets = smooth_chain_targets(np.asarray(targets, np.float64), parents)
    lv = _levels(parents)
    height = max(float(np.ptp(rest[:, 2])), 1.0)
    out = np.empty((F, N, 3))
    acc = np.zeros((F, N, 3))
    out[0] = rest
    alpha1 = {}
    for d, (nodes, par, grand) in enumerate(zip(lv.nodes, lv.parents, lv.grand)):
        alpha1[d] = branch_angle(rest[nodes], rest[par], _grand_or_none(rest, grand, par))
    X = rest.astype(np.float64).copy()
    A = np.zeros((N, 3))
    conf = np.ones((F, N)) if confidence is None else np.maximum(np.asarray(confidence, np.float64), 0.05)
    for t in range(1, F):
        if params.solver == "deterministic":
            X = _deterministic_frame(X, parents, lv, targets[t])
        else:
            _probabilistic_frame(X, A, lv, targets[t], level, alpha1, height, params, conf[t])
        out[t] = X
        acc[t] = A
        if t % 10 == 0:
            report(progress, "motion", t / (F - 1))
    report(progress, "motion", 1.0)
    return Motion(out.astype(np.float32), acc.astype(np.float32))


def _grand_or_none(X, grand, par):
    """Grandparent positions, with the vertical stand-in for root edges (x − (0, 0, 1))."""
    g = X[np.maximum(grand, 0)].copy()
    g[grand < 0] = X[par[grand < 0]] - np.array([0.0, 0.0, 1.0])
    return g


def _probabilistic_frame(X, A, lv: _Levels, target, level, alpha1, height, prm: MotionParams,
                         conf: np.ndarray) -> None:
    """One frame, in place on ``X (N, 3)`` and the accumulated rotations ``A (N, 3)``; ``conf (N,)``
    weights each node's track term."""
    s_track = prm.sigma_track * height
    lam = 1.0 / prm.prior_sigma ** 2
    lam_rest = 1.0 / prm.rest_sigma ** 2
    s_depth = prm.depth_sigma * height
    for d, (nodes, par, grand, slot, mem) in enumerate(zip(lv.nodes, lv.parents, lv.grand, lv.slot, lv.member)):
        B = len(nodes)
        sigma_shape = prm.sigma_shape * (1 + prm.sigma_shape_growth * level[nodes])
        y0 = X[mem, 1].copy()              # depths before this level's rotations
        A0 = A[nodes].copy()
        wf = np.zeros((B, 3))              # this frame's rotation so far (GN iterate)
        for _ in range(prm.iterations):
            v = X[mem] - X[par[slot]]                                  # (M, 3)
            r = X[mem][:, [0, 2]] - target[mem]                        # (M, 2)
            # J = K · (−[v]×): rows x and z of −[v]×
            J = np.zeros((len(mem), 2, 3))
            J[:, 0, 1], J[:, 0, 2] = v[:, 2], -v[:, 1]
            J[:, 1, 0], J[:, 1, 1] = v[:, 1], -v[:, 0]
            wt = conf[mem] / s_track ** 2
            JTJ = np.einsum("mki,mkj->mij", J, J) * wt[:, None, None]
            JTr = np.einsum("mki,mk->mi", J, r) * wt[:, None]
            # depth steps of the subtree (row y of −[v]×), measured from before this level moved
            Jy = np.stack([-v[:, 2], np.zeros(len(v)), v[:, 0]], 1)
            JTJ += Jy[:, :, None] * Jy[:, None, :] / s_depth ** 2
            JTr += Jy * ((X[mem, 1] - y0) / s_depth ** 2)[:, None]
            H = np.zeros((B, 3, 3))
            g = np.zeros((B, 3))
            np.add.at(H, slot, JTJ)
            np.add.at(g, slot, JTr)
            # shape term: α(ω) ≈ α − ω · (u × w) / sin α
            u = X[nodes] - X[par]
            u /= np.maximum(np.linalg.norm(u, axis=1), 1e-12)[:, None]
            w = _parent_dirs(X, par, grand)
            cos = np.clip(np.sum(u * w, 1), -1, 1)
            alpha = np.arccos(cos)
            sin = np.maximum(np.sqrt(1 - cos ** 2), 1e-3)
            ga = -np.cross(u, w) / sin[:, None]                         # dα/dω
            res = (alpha - alpha1[d]) / sigma_shape
            gs = ga / sigma_shape[:, None]
            H += gs[:, :, None] * gs[:, None, :]
            g += gs * res[:, None]
            H += (lam + lam_rest) * np.eye(3)[None]
            g += lam * wf + lam_rest * (A0 + wf)
            step = -np.linalg.solve(H, g[..., None])[..., 0]
            new_wf = np.clip(wf + step, -prm.max_step, prm.max_step)    # uniform prior's box
            total = A0 + new_wf
            norm = np.linalg.norm(total, axis=1)
            over = norm > prm.max_total                                  # |Σ r| ≤ Δ
            if over.any():
                total[over] *= (prm.max_total / norm[over])[:, None]
                new_wf = total - A0
            R = rodrigues(new_wf - wf)                                   # (B, 3, 3)
            X[mem] = X[par[slot]] + np.einsum("mij,mj->mi", R[slot], X[mem] - X[par[slot]])
            wf = new_wf
            A[nodes] = total


def _deterministic_frame(Xprev: np.ndarray, parents: np.ndarray, lv: _Levels, target: np.ndarray) -> np.ndarray:
    """Sphere ∩ line of sight, root to leaf (see module docstring); returns the new ``(N, 3)``."""
    X = Xprev.copy()
    length = np.zeros(len(parents))
    for nodes, par in zip(lv.nodes, lv.parents):
        length[nodes] = np.linalg.norm(Xprev[nodes] - Xprev[par], axis=1)
    for nodes, par in zip(lv.nodes, lv.parents):
        p = X[par]
        l = length[nodes]
        tgt = target[nodes].astype(np.float64)
        prev2 = Xprev[nodes][:, [0, 2]]
        d2 = np.linalg.norm(tgt - p[:, [0, 2]], axis=1)
        far = d2 > l
        if far.any():
            # pull the target toward the previous projection until it is within reach: solve
            # |p + (prev + s (tgt − prev)) − p|  = l for the largest s in [0, 1]
            a = tgt[far] - prev2[far]
            b = prev2[far] - p[far][:, [0, 2]]
            qa = np.sum(a * a, 1)
            qb = 2 * np.sum(a * b, 1)
            qc = np.sum(b * b, 1) - l[far] ** 2
            disc = np.maximum(qb ** 2 - 4 * qa * qc, 0.0)
            s = np.clip((-qb + np.sqrt(disc)) / np.maximum(2 * qa, 1e-12), 0.0, 1.0)
            tgt[far] = prev2[far] + s[:, None] * a
            d2 = np.linalg.norm(tgt - p[:, [0, 2]], axis=1)
        dy = np.sqrt(np.maximum(l ** 2 - np.minimum(d2, l) ** 2, 0.0))
        y_a, y_b = p[:, 1] + dy, p[:, 1] - dy
        y = np.where(np.abs(y_a - Xprev[nodes, 1]) <= np.abs(y_b - Xprev[nodes, 1]), y_a, y_b)
        new = np.stack([tgt[:, 0], y, tgt[:, 1]], 1)
        # exact length (the pull can leave the target a hair outside the sphere)
        vec = new - p
        new = p + vec * (l / np.maximum(np.linalg.norm(vec, axis=1), 1e-12))[:, None]
        X[nodes] = new
    return X
