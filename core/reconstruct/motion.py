"""Stage 7 — 3D motion from the moving 2D skeleton (paper §4).

Every node i rotates its subtree about its parent joint p by a small rotation r_i(t) per frame
(a rotation vector ω, world axes). Frame by frame the probabilistic solver maximizes, over the
rotations of all nodes at once,

    p(r(t)) ∝ Π_j exp(−c_j(t) |K x_j(t) − x'_j(t)|² / 2σ_track²)              track term
            · Π_i exp(−(α_i(t) − α_i(1))² / 2σ_shape(d_i)²)                   shape term
            · Π_i U(ω_i; [−δ_r, δ_r]³)                                        per-frame prior
            · Π_i [|Σ_τ r_i(τ)| ≤ Δ]                                          accumulated bound

with K the orthographic projection along depth (x, z), x' the tracked 2D position, c_j(t) the 2D
motion confidence of node j (what the tracks measured there, :mod:`.node_motion`; floored at
0.05: a node moved by a guess pulls little), α the angle between the branch and its parent
branch, σ_shape growing with the branching level d_i. Instead of a grid search it takes a few
Gauss–Newton steps on the linearized terms (R(ω)v ≈ v + ω × v) with a weak Gaussian on ω that fixes
the otherwise free twist, then clips ω to the prior's box and to the Δ ball. Two terms the paper
does not have keep what a single camera cannot see from drifting (measured on synthetic trees,
without them the accumulated rotations ran into Δ and tips swung 3× the true depth): a Gaussian on
the depth step each rotation gives its subtree's nodes and a weak pull of the accumulated rotation
back to rest. Each Gauss–Newton step is one sparse linear solve over the whole tree
(:mod:`.rotation_solve`); an earlier version solved depth by depth, root to leaf (36 sequential
solves a frame on the broad sample, 13 ms a frame against 1.5 ms, reprojection median 0.19 % of the
height against 0.13 %). Branch lengths stay exact (only rotations are applied).

The deterministic baseline places each node where the sphere about its parent joint (radius the
branch length) meets the line of sight through its tracked 2D position, taking the intersection
nearer its previous depth; with no intersection the target is pulled toward the previous
projection until there is one.

All coordinates are pixels of frame 1 in the lift's plane frame (x right, y depth, z up, origin
at the trunk base).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..params import param
from ..progress import ProgressFn, report
from ..topology import chains, node_depths
from .node_motion import LOW_CONFIDENCE
from .rotation_solve import PENALTY, FrameTerms, TreeSystem, branch_angles, gauss_newton_step, turn

SOLVERS = ("probabilistic", "deterministic")

@dataclass
class MotionParams:
    """σ and bounds of the probabilistic solver (lengths as shares of the tree height, angles in
    radians). ``solver`` is "probabilistic" (default) or "deterministic"."""

    solver: str = param("probabilistic", choices=SOLVERS, what="solver")
    sigma_track: float = param(0.0075, 0.0005, 0.2, what="--sigma-track")      # of the tree height
    sigma_shape: float = param(0.04, 0.001, 1.0, what="--sigma-shape", unit="rad")   # at level 0 …
    sigma_shape_growth: float = 0.5   # … times (1 + growth · level)
    max_step: float = param(0.15, 0.01, 1.0, what="--max-step", unit="rad")   # δ_r: per-frame bound per axis
    max_total: float = param(float(np.pi / 4), 0.05, 3.14, what="--max-total", unit="rad")  # Δ: accumulated bound
    depth_sigma: float = 0.01         # per-frame depth step of subtree nodes (share of the height):
                                      # what the camera cannot see should not swing freely
    rest_sigma: float = 0.15          # radians: weak pull of the accumulated rotation back to rest
    rest_sigma_conifer: float = 0.5   # … for a conifer (:meth:`for_form`)
    prior_sigma: float = 0.5          # weak Gaussian on ω (fixes the free twist), radians
    iterations: int = 2               # Gauss–Newton steps a frame at most …
    step_tolerance: float = 1e-4      # … stopping once a step moved every node to within this
                                      # (share of the height) of where its linearization said

    def for_form(self, conifer: bool) -> MotionParams:
        """These parameters for a tree of that form: a conifer's pull back to rest is
        ``rest_sigma_conifer``. Its whorl branches swing about one stiff trunk, and the pull at
        0.15 rad held them at 0.3–0.5× the truth's bending (95th percentile of the change of
        branch angles without the truth's swinging twigs, ``benchmarks/motion_truth.py``); at
        0.5 rad every conifer clip measured moved toward its truth and none past it (held-out
        conifer storm 2.7 → 4.2° and 2.9 → 4.5° for 6.3 and 5.9°, tiny 2.7 → 3.1° and 2.0 → 2.5°
        for 8.8 and 8.2°, conifer 1.3 → 1.8° and 1.3 → 1.7° for 2.3 and 2.2°; tip correlation
        the same). On broadleaves the looser pull followed the tracks' noise past the truth
        (gusts 3.2 → 4.5° for 2.6°, palm 3.0 → 4.0° for 2.8°), so they keep ``rest_sigma``."""
        return replace(self, rest_sigma=self.rest_sigma_conifer) if conifer else self


@dataclass
class Motion:
    """``nodes (F, N, 3)`` px per frame; ``accumulated (F, N, 3)`` Σ ω per node (radians)."""

    nodes: np.ndarray
    accumulated: np.ndarray


def _levels(parents: np.ndarray) -> list[np.ndarray]:
    """Nodes per tree depth (1, 2, …): what the deterministic solver places one after another."""
    depth = node_depths(parents)
    return [np.flatnonzero(depth == d) for d in range(1, int(depth.max(initial=0)) + 1)]


def smooth_chain_targets(targets: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Tracked positions ``(F, N, 2)`` with every chain node (exactly one child, not the root)
    moved along its chain by interpolating the displacements of the chain's two end nodes (branch
    points, tips or the root) by arc length, its own displacement across the chain kept.

    Each 2D node follows its own nearby tracks, so a chain's edges stretch and shrink with tracker
    noise; a 3D branch of fixed length cannot follow stretching and turns compression into spurious
    swings in depth. That noise runs along the chain. Across it is the branch's bending, which an
    interpolation of the ends cannot show (a bent limb's middle does not move on the chord of its
    ends): measured on the synthetic clips, replacing the whole displacement left the 3D up to
    5.2 % of the height from the measured 2D at a gust's peak (broad, gusts), keeping the part
    across 2.5–2.7 %. Across is the normal of the interpolated chain at the node, per frame."""
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
    child = np.zeros(N, int)
    kids = np.flatnonzero(parents >= 0)
    child[parents[kids]] = kids                        # a chain node's one child
    tangent = out[:, child[chain]] - out[:, parents[chain]]
    tangent /= np.maximum(np.linalg.norm(tangent, axis=-1, keepdims=True), 1e-9)
    normal = np.stack([-tangent[..., 1], tangent[..., 0]], -1)
    across = np.sum((targets[:, chain] - out[:, chain]) * normal, -1, keepdims=True)
    out[:, chain] += across * normal
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
    out = np.empty((F, N, 3))
    acc = np.zeros((F, N, 3))
    out[0] = rest
    levels = _levels(parents) if params.solver == "deterministic" else []
    solver = None if levels else _Probabilistic(rest, parents, level, params)
    for t in range(1, F):
        if solver is None:
            out[t] = _deterministic_frame(out[t - 1], parents, levels, targets[t])
        else:
            out[t] = solver.frame(targets[t], None if confidence is None else confidence[t])
            acc[t, solver.sys.nodes] = solver.A
        if t % 10 == 0:
            report(progress, "motion", t / (F - 1))
    report(progress, "motion", 1.0)
    return Motion(out.astype(np.float32), acc.astype(np.float32))


#: how far (share of the tree height) a node's 3D position, projected back into the frame, may lie
#: from its measured 2D position at a measured node-frame (issue 35); farther, the run warns
REPROJECTION_BOUND = 0.03
#: a node-frame is unmeasured when its 2D distance to an ancestor (its parent first), or a
#: descendant's to it, is longer than the bones between them by this much (share of the height)
#: per edge between them: no rigid branch reaches it, the tracker stretched it (:func:`out_of_reach`)
STRETCH_TOLERANCE = 0.005


@dataclass
class MotionFit:
    """How closely the 3D motion keeps to the measured 2D motion it was solved from.

    ``reprojection (F, N)`` the distance of each node's projection from its measured 2D position
    (share of the tree height, frame 1 zero); ``measured (F, N)`` the node-frames the bound holds
    for: motion confidence at least ``LOW_CONFIDENCE`` (:mod:`.node_motion`) and within reach of
    every ancestor and descendant (:func:`out_of_reach`)."""

    reprojection: np.ndarray
    measured: np.ndarray

    def summary(self) -> dict:
        """``{median, max, unmeasured, over}``: median over every node-frame, max over the measured
        ones (shares of the height), the unmeasured share and how many measured node-frames lie
        beyond ``REPROJECTION_BOUND``; what ``meta["motion_fit"]`` records."""
        r, m = self.reprojection[1:], self.measured[1:]
        return {"median": round(float(np.median(r)) if r.size else 0.0, 5),
                "max": round(float(r[m].max(initial=0.0)), 5),
                "unmeasured": round(float(1 - m.mean()) if m.size else 0.0, 5),
                "over": int((r[m] > REPROJECTION_BOUND).sum())}


def out_of_reach(rest: np.ndarray, parents: np.ndarray, targets: np.ndarray, tolerance: float) -> np.ndarray:
    """``(F, N)`` node-frames no rigid tree can reach: the 2D distance between the node's target
    and an ancestor's (``targets (F, N, 2)`` px) exceeds the length of the bones between them in
    the rest pose ``rest (N, 3)`` px by more than ``tolerance`` px per edge between them. A
    stretched edge marks both its ends (which of the two the tracker moved is unknown); a longer
    path marks its lower end only, the node farther from the trunk, so one mis-tracked tip does not
    take its limb and the trunk out of the count. The longer paths catch what the edges miss: the
    nodes below a stretched edge that follow its lower end. On dense 101 the edge above a tip's
    parent was tracked 5.6 % of the height past its bone, the tip followed its parent, and the tip,
    where the 3D strayed 4.2 % from it, was counted measured. One pass per ancestor
    generation, vectorized over nodes and frames."""
    N = len(parents)
    bone = np.zeros(N)
    kids = np.flatnonzero(parents >= 0)
    bone[kids] = np.linalg.norm(rest[kids] - rest[parents[kids]], axis=-1)
    bad = np.zeros(targets.shape[:2], bool)
    node, anc, path = kids, parents[kids], bone[kids]
    k = 1                                                          # edges between node and anc
    while len(node):
        far = np.linalg.norm(targets[:, node] - targets[:, anc], axis=-1) - path > k * tolerance    # (F, n)
        np.logical_or.at(bad.T, node, far.T)
        if k == 1:                                                 # the edge's upper end, too
            np.logical_or.at(bad.T, anc, far.T)
        up = parents[anc] >= 0
        node, path, anc, k = node[up], path[up] + bone[anc[up]], parents[anc[up]], k + 1
    return bad


def motion_fit(nodes: np.ndarray, parents: np.ndarray, targets: np.ndarray,
               confidence: np.ndarray | None = None) -> MotionFit:
    """:class:`MotionFit` of a solved motion ``nodes (F, N, 3)`` px (plane frame) against its
    measured targets ``(F, N, 2)`` (x, z) px and their ``confidence (F, N)`` (None: all measured);
    the height is the rest pose's."""
    X = np.asarray(nodes, np.float64)
    T = np.asarray(targets, np.float64)
    height = max(float(np.ptp(X[0, :, 2])), 1.0)
    reprojection = np.linalg.norm(X[..., [0, 2]] - T, axis=-1) / height
    measured = np.ones(T.shape[:2], bool) if confidence is None else np.asarray(confidence) >= LOW_CONFIDENCE
    bad = out_of_reach(X[0], parents, T, STRETCH_TOLERANCE * height)
    return MotionFit(reprojection, measured & ~bad)


def fit_warning(summary: dict) -> str | None:
    """One line when the 3D motion strays past ``REPROJECTION_BOUND`` at a measured node-frame."""
    if summary["max"] <= REPROJECTION_BOUND:
        return None
    return (f"the 3D motion strays up to {summary['max']:.1%} of the tree's height from the measured 2D motion "
            f"at {summary['over']} node-frame(s) (bound {REPROJECTION_BOUND:.0%}); a lower --sigma-track "
            f"follows the tracks more closely")


class _Probabilistic:
    """The probabilistic solver's state between frames: positions ``X (N, 3)`` px and the
    accumulated rotations ``A (n, 3)`` radians of the non-root nodes ``sys.nodes``."""

    def __init__(self, rest: np.ndarray, parents: np.ndarray, level: np.ndarray, prm: MotionParams):
        self.prm = prm
        self.sys = sys_ = TreeSystem.of(parents)
        self.grand = parents[sys_.par]
        self.X = rest.astype(np.float64).copy()
        self.A = np.zeros((len(sys_.nodes), 3))
        height = max(float(np.ptp(rest[:, 2])), 1.0)
        self.inv_track = 1.0 / (prm.sigma_track * height) ** 2
        self.tol = prm.step_tolerance * height
        self.terms = dict(inv_depth=1.0 / (prm.depth_sigma * height) ** 2,
                          sigma_shape=prm.sigma_shape * (1 + prm.sigma_shape_growth * np.asarray(level)[sys_.nodes]),
                          alpha1=branch_angles(self.X, sys_, self.grand)[2], prior=1.0 / prm.prior_sigma ** 2,
                          rest=1.0 / prm.rest_sigma ** 2, penalty=PENALTY * self.inv_track)

    def frame(self, target: np.ndarray, confidence: np.ndarray | None) -> np.ndarray:
        """The next frame's positions ``(N, 3)`` from its targets ``(N, 2)`` and confidence ``(N,)``."""
        prm, sys_, nodes = self.prm, self.sys, self.sys.nodes
        c = 1.0 if confidence is None else np.maximum(np.asarray(confidence, np.float64)[nodes], 0.05)
        terms = FrameTerms(track=np.broadcast_to(c * self.inv_track, len(nodes)), target=target[nodes], **self.terms)
        X, A0 = self.X, self.A
        wf = np.zeros_like(A0)
        total = A0
        dw = np.zeros_like(X)
        for _ in range(prm.iterations):
            step, predicted = gauss_newton_step(X, wf, A0, sys_, self.grand, terms)
            predicted += X[nodes][:, [0, 2]]
            new = np.clip(wf + step, -prm.max_step, prm.max_step)       # the uniform prior's box, then
            total = A0 + new
            norm = np.linalg.norm(total, axis=1)                         # |Σ r| ≤ Δ
            over = norm > prm.max_total
            if over.any():
                total[over] *= (prm.max_total / norm[over])[:, None]
                new = total - A0
            dw[nodes] = new - wf
            X = turn(X, dw, sys_)
            wf = new
            if np.abs(X[nodes][:, [0, 2]] - predicted).max(initial=0.0) < self.tol:
                break
        self.X, self.A = X, total
        return X


def _deterministic_frame(Xprev: np.ndarray, parents: np.ndarray, levels: list[np.ndarray],
                         target: np.ndarray) -> np.ndarray:
    """Sphere ∩ line of sight, root to leaf (see module docstring); returns the new ``(N, 3)``."""
    X = Xprev.copy()
    length = np.zeros(len(parents))
    for nodes in levels:
        length[nodes] = np.linalg.norm(Xprev[nodes] - Xprev[parents[nodes]], axis=1)
    for nodes in levels:
        p = X[parents[nodes]]
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
