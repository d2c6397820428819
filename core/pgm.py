"""Species model — the probabilistic generative model (PGM) of paper §5.1–5.2.

Features of a reconstructed :class:`~.tree3d.Tree3D`:

* **Shape, per bifurcation** (apex ``i`` with two children; local root ``j`` = the previous
  branch point or the trunk base up the chain; local leaves ``k``, ``l`` = the next branch point or
  tip down each child's chain). In the picture plane (x, z of frame 0 — the plane the video saw
  and the one a new tree grows in) the three angles around the apex sum to 2π. They are taken
  in a canonical order: from the direction back to the local root, turning toward the
  *continuing* child first (the one that deviates least from the parent branch), then to the
  side child, then back: ``θ1`` (back → continuation), ``θ2`` (continuation → side), ``θ3``
  (side → back); the turning sense is counter-clockwise or, for a mirrored bifurcation,
  clockwise (``mirrored``; the model keeps the share of mirrored ones). The feature is
  ``⟨θ1:θ2:θ3⟩ / 2π`` (sums to 1); the branch lengths (chords, metres)
  ``⟨L1:L2:L3⟩ = ⟨|j i| : |i cont| : |i side|⟩ / Σ`` in the same order. (A fixed
  counter-clockwise order makes the data bimodal — continuation on the left or on the right —
  which one Dirichlet cannot hold; generated limbs then lose their leader and curl.)
* **Motion, per node and rotation axis**: ``ω_a(t)`` is the node's rotation relative to its
  parent bone (rotation vector, radians, world axes a = x, y, z; from
  :func:`.bones.world_rotations`). ``X_k = rfft(ω_a − mean)``; keep bins ``k = 1..K`` (the
  lowest ~20 %). ``X`` is turned by one phase so the node's own strongest bin is real positive
  (motion features must not depend on the time origin, as shape features do not depend on
  position), scaled by its L1 size ``S = Σ_k |c_k| + |d_k|`` (``c + i d = X``), so
  ``u = c / S``, ``v = d / S`` lie in [−1, 1] with ``Σ u ≤ 1``; shifted by +1 (non-negative) and
  closed with one slack component so each tuple sums to 1 and the shift is exactly removable:

      z = ⟨u_1 + 1, …, u_K + 1, 1 − Σ u⟩ / (K + 1)        u_k = (K + 1) z_k − 1

  (same for ``v``). The energy ratios ``|X_k|² / Σ_j |X_j|²`` (the paper's "ratio between the
  energy of each given frequency") get their own Dirichlet: with random phases the mean of ``u``
  is ~0 at every bin, so the real/imag tuples alone cannot say which frequency dominates. The
  RMS of the node's rotation (radians) is log-normal with a linear trend in the node's
  normalized depth; the spread of the phases at the dominant bin is kept too.

Each tuple set gets a Dirichlet fitted by maximum likelihood (:func:`fit_dirichlet`, Minka 2003).
A :class:`SpeciesModel` is saved as human-readable JSON (:func:`save_species`).
"""
from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import dataclass, field

import numpy as np
from scipy.special import digamma, gammaln, polygamma

from .errors import InputError

FORMAT = "tree_from_video.species"
VERSION = 1
AXES = ("x", "y", "z")
KEEP_FRACTION = 0.2              # lowest share of the frequency bins kept as "dominant"
MIN_VALUE = 1e-12                # zeros in a tuple are clipped to this before log (fallback)
MAX_PRECISION = 1e5              # cap of s = Σα (identical samples drive the ML s to ∞)
DEFAULT_PRECISION = 20.0         # s used when there is too little data to estimate it


# ============================================================================ Dirichlet

@dataclass
class DirichletFit:
    """A fitted Dirichlet ``D(z | α)``: ``alpha (K,)`` > 0; ``loglik`` mean log-likelihood per
    sample after the start and after every fixed-point iteration; ``fallback`` None for a clean
    maximum-likelihood fit, else why another estimate was used; ``n_samples`` rows used."""

    alpha: np.ndarray
    loglik: list = field(default_factory=list)
    fallback: str | None = None
    n_samples: int = 0
    iterations: int = 0

    @property
    def precision(self) -> float:
        """``s = Σ_k α_k``: large → samples close to the mean."""
        return float(np.sum(self.alpha))

    @property
    def mean(self) -> np.ndarray:
        """``m = α / s`` ``(K,)``."""
        return self.alpha / self.precision

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``(n, K)`` samples, every row positive and summing to 1."""
        z = rng.dirichlet(self.alpha, size=n)
        z = np.where(np.isfinite(z), z, 0.0)
        z = np.maximum(z, 1e-12)
        return z / z.sum(axis=1, keepdims=True)


def inv_digamma(y: np.ndarray, iterations: int = 5) -> np.ndarray:
    """``x`` with ``ψ(x) = y`` (elementwise) by Newton's method from Minka's (2003, App. C) start
    ``x0 = exp(y) + 1/2`` for ``y ≥ −2.22``, else ``−1 / (y − ψ(1))``; five steps reach 14 digits."""
    y = np.asarray(y, np.float64)
    x = np.where(y >= -2.22, np.exp(np.minimum(y, 700.0)) + 0.5, -1.0 / (y - digamma(1.0)))
    for _ in range(iterations):
        x = x - (digamma(x) - y) / polygamma(1, x)
        x = np.maximum(x, 1e-300)
    return x


def dirichlet_loglik(alpha: np.ndarray, mean_log: np.ndarray) -> float:
    """Mean log-likelihood per sample of Eq. 11:
    ``log Γ(Σα) − Σ log Γ(α_k) + Σ (α_k − 1) · mean_n log z_nk`` (``mean_log (K,)``)."""
    alpha = np.asarray(alpha, np.float64)
    return float(gammaln(alpha.sum()) - gammaln(alpha).sum() + np.dot(alpha - 1.0, mean_log))


def _best_precision(mean: np.ndarray, mean_log: np.ndarray) -> float:
    """Start for the precision: the best ``s`` on a log grid (0.1 … MAX_PRECISION) for α = s·m.
    (The moment estimate of s is thrown far off by one low-variance component, and the Newton
    step from there leaves the positive orthant.)"""
    grid = np.logspace(-1.0, np.log10(MAX_PRECISION), 81)
    ll = [dirichlet_loglik(g * mean, mean_log) for g in grid]
    return float(grid[int(np.argmax(ll))])


def _newton_step(alpha: np.ndarray, mean_log: np.ndarray) -> np.ndarray:
    """Newton direction ``H⁻¹ g`` for the mean log-likelihood (Minka eq. 15–18): the Hessian is
    ``diag(q) + z 11ᵀ`` with ``q_k = −ψ'(α_k)``, ``z = ψ'(Σα)``, so
    ``(H⁻¹g)_k = (g_k − b) / q_k``, ``b = Σ_j (g_j/q_j) / (1/z + Σ_j 1/q_j)``."""
    g = digamma(alpha.sum()) - digamma(alpha) + mean_log
    q = -polygamma(1, alpha)
    z = polygamma(1, alpha.sum())
    b = np.sum(g / q) / (1.0 / z + np.sum(1.0 / q))
    return (g - b) / q


def _fit_precision(mean: np.ndarray, mean_log: np.ndarray, max_iter: int) -> tuple[np.ndarray, list, bool]:
    """ML precision with the mean fixed (Minka §3.3): maximize
    ``f(s) = log Γ(s) − Σ log Γ(s m_k) + s Σ m_k mean_log_k`` by safeguarded Newton,
    ``f'(s) = ψ(s) − Σ m_k ψ(s m_k) + Σ m_k mean_log_k``, ``f''(s) = ψ'(s) − Σ m_k² ψ'(s m_k)``."""
    s = _best_precision(mean, mean_log)
    hist = [dirichlet_loglik(s * mean, mean_log)]
    for _ in range(max_iter):
        d1 = digamma(s) - np.dot(mean, digamma(s * mean)) + np.dot(mean, mean_log)
        d2 = polygamma(1, s) - np.dot(mean ** 2, polygamma(1, s * mean))
        step = -d1 / d2 if d2 < 0 else np.sign(d1) * s
        for t in (1.0, 0.5, 0.25, 0.125, 0.0625):
            cand = min(s + t * step, MAX_PRECISION)
            if cand > 0:
                ll = dirichlet_loglik(cand * mean, mean_log)
                if ll > hist[-1]:
                    break
        else:
            break
        if ll - hist[-1] <= 1e-12 * max(1.0, abs(ll)):
            break
        s = cand
        hist.append(ll)
        if s >= MAX_PRECISION:
            return s * mean, hist, True
    return s * mean, hist, False


def fit_dirichlet(X: np.ndarray, max_iter: int = 2000, fixed_mean: np.ndarray | None = None) -> DirichletFit:
    """Maximum-likelihood Dirichlet for rows ``X (S, K)`` of proportions (each row is normalized
    to sum 1 first).

    Minka's fixed point ``α_k ← ψ⁻¹(ψ(Σ_j α_j) + mean_n log z_nk)`` (Minka 2003 eq. 9; ψ⁻¹ by
    Newton, :func:`inv_digamma`), started from the sample mean with the best precision on a grid;
    each step maximizes a lower bound of the likelihood, so the log-likelihood never decreases.
    Where a (backtracked) Newton step on α raises the likelihood more than the fixed-point step it
    is taken instead (the fixed point alone needs thousands of steps when the precision is large);
    the history stays non-decreasing either way. Iteration stops when a step gains less than
    1e-12 (relative).

    ``fixed_mean``: keep the mean ``m (K,)`` (e.g. the sample mean) and fit only the precision
    by maximum likelihood (Minka §3.3).

    Degenerate data never gives NaN; ``fallback`` says what was done:

    * rows with non-finite entries or a non-positive sum are dropped; negative entries count as 0;
    * no usable row → ``α = 1`` (uniform);
    * fewer rows than dimensions (``S < K``) or a single row → the ML precision is not
      identifiable: ``α = DEFAULT_PRECISION · mean`` (mean of the rows, zeros clipped);
    * exact zeros → clipped to ``min(MIN_VALUE, smallest positive entry)`` and renormalized
      before the logarithm;
    * (nearly) identical rows → the precision is capped at ``MAX_PRECISION`` (the ML estimate is
      infinite): ``α = MAX_PRECISION · mean``.
    """
    X = np.asarray(X, np.float64)
    if X.ndim != 2 or X.shape[1] < 2:
        raise ValueError(f"fit_dirichlet needs (samples, K>=2) data, got shape {X.shape}")
    K = X.shape[1]
    notes = []
    X = X[np.all(np.isfinite(X), axis=1)]
    if (X < 0).any():
        notes.append("negative entries set to 0")
        X = np.maximum(X, 0.0)
    X = X[X.sum(axis=1) > 0]
    S = len(X)
    if S == 0:
        return DirichletFit(np.ones(K), [], "no usable samples: uniform α = 1", 0, 0)
    Z = X / X.sum(axis=1, keepdims=True)
    if (Z <= 0).any():
        floor = min(MIN_VALUE, float(Z[Z > 0].min()))
        notes.append(f"zeros clipped to {floor:.3g}")
        Z = np.maximum(Z, floor)
        Z /= Z.sum(axis=1, keepdims=True)
    mean = Z.mean(axis=0)
    if fixed_mean is not None:
        mean = np.maximum(np.asarray(fixed_mean, np.float64), MIN_VALUE)
        mean = mean / mean.sum()
    mean_log = np.log(Z).mean(axis=0)
    if S < max(K, 2):
        alpha = DEFAULT_PRECISION * mean
        notes.insert(0, f"{S} sample(s) for {K} dimensions: mean with precision {DEFAULT_PRECISION:g}")
        return DirichletFit(alpha, [dirichlet_loglik(alpha, mean_log)], "; ".join(notes), S, 0)
    if np.all(np.ptp(Z, axis=0) < 1e-9):
        alpha = MAX_PRECISION * mean
        notes.insert(0, f"identical samples: precision capped at {MAX_PRECISION:g}")
        return DirichletFit(alpha, [dirichlet_loglik(alpha, mean_log)], "; ".join(notes), S, 0)
    if fixed_mean is not None:
        alpha, hist, capped = _fit_precision(mean, mean_log, max_iter)
        if capped:
            notes.insert(0, f"precision capped at {MAX_PRECISION:g} (nearly identical samples)")
        return DirichletFit(alpha, hist, "; ".join(notes) or None, S, len(hist) - 1)
    alpha = _best_precision(mean, mean_log) * mean
    hist = [dirichlet_loglik(alpha, mean_log)]
    it = 0
    capped = False
    for it in range(1, max_iter + 1):
        # Minka's fixed point: α_k ← ψ⁻¹(ψ(Σα) + mean log z_k)  (never lowers the likelihood)
        new = inv_digamma(digamma(alpha.sum()) + mean_log)
        ll = dirichlet_loglik(new, mean_log)
        step = _newton_step(alpha, mean_log)
        for t in (1.0, 0.5, 0.25):
            nw = alpha - t * step
            if np.all(nw > 0) and np.all(np.isfinite(nw)):
                ll_n = dirichlet_loglik(nw, mean_log)
                if ll_n > ll:
                    new, ll = nw, ll_n
                break
        if new.sum() > MAX_PRECISION:               # the ML precision runs away: cap it
            new = new * (MAX_PRECISION / new.sum())
            ll = dirichlet_loglik(new, mean_log)
            if ll > hist[-1]:
                alpha = new
                hist.append(ll)
            capped = True
            break
        if ll - hist[-1] <= 1e-12 * max(1.0, abs(ll)):
            break                                    # converged (gain below round-off)
        alpha = new
        hist.append(ll)
    if capped:
        notes.insert(0, f"precision capped at {MAX_PRECISION:g} (nearly identical samples)")
    return DirichletFit(alpha, hist, "; ".join(notes) or None, S, it)


# ============================================================================ features

def anchor_links(parents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``up (N,)``: nearest strict ancestor that is an anchor (root or branch point; −1 for the
    root); ``down (N,)``: for every node, the first anchor or tip at or below it along single-child
    chains (the node itself if it is a branch point or a tip)."""
    from .skeleton2d import children_lists, topological_order
    parents = np.asarray(parents)
    N = len(parents)
    ch = children_lists(parents)
    n_kids = np.array([len(c) for c in ch])
    anchor = (n_kids >= 2) | (parents < 0)
    order = topological_order(parents)
    up = np.full(N, -1)
    for n in order:
        p = parents[n]
        if p >= 0:
            up[n] = p if anchor[p] else up[p]
    down = np.arange(N)
    for n in order[::-1]:
        if n_kids[n] == 1 and parents[n] >= 0:
            down[n] = down[ch[n][0]]
    return up, down


@dataclass
class BifurcationFeatures:
    """Per bifurcation ``b``: ``apex (B,)``, ``root (B,)`` local root node, ``leaves (B, 2)``
    local leaf nodes (continuation, side); ``angles (B, 3)`` ⟨θ1:θ2:θ3⟩ and ``lengths (B, 3)``
    ⟨L1:L2:L3⟩, each row summing to 1; ``chord (B, 3)`` metres ``(L1, L2, L3)``; ``mirrored
    (B,)`` bool, True where the canonical turning sense is clockwise."""

    apex: np.ndarray
    root: np.ndarray
    leaves: np.ndarray
    angles: np.ndarray
    lengths: np.ndarray
    chord: np.ndarray
    mirrored: np.ndarray


def ccw_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Counter-clockwise angle in [0, 2π) from 2D direction ``a (..., 2)`` to ``b (..., 2)``."""
    ang = np.arctan2(b[..., 1], b[..., 0]) - np.arctan2(a[..., 1], a[..., 0])
    return np.mod(ang, 2 * np.pi)


def canonical_angles(back: np.ndarray, c1: np.ndarray, c2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Canonical ``θ (B, 3)`` radians (sum 2π), ``cont_first (B,)`` bool (True: ``c1`` is the
    continuation) and ``mirrored (B,)`` bool, for 2D directions ``back``, ``c1``, ``c2 (B, 2)``.

    With ``a1 = ccw(back, c1)`` and ``a2 = ccw(back, c2)``, the continuation is the child whose
    ccw angle is nearer π. Counter-clockwise from ``back`` the children come in the order
    (min, max) of (a1, a2) with gaps ``(min, max − min, 2π − max)``; if the continuation is the
    first of them the sense is counter-clockwise, else clockwise and the gaps are read backwards:
    ``(2π − max, max − min, min)``."""
    a1, a2 = ccw_angle(back, c1), ccw_angle(back, c2)
    cont_first = np.abs(a1 - np.pi) <= np.abs(a2 - np.pi)
    lo, hi = np.minimum(a1, a2), np.maximum(a1, a2)
    gaps = np.stack([lo, hi - lo, 2 * np.pi - hi], axis=1)
    cont_angle = np.where(cont_first, a1, a2)
    mirrored = cont_angle > lo + 1e-12        # the continuation is the second counter-clockwise
    theta = np.where(mirrored[:, None], gaps[:, ::-1], gaps)
    return theta, cont_first, mirrored


def bifurcation_features(parents: np.ndarray, pos: np.ndarray) -> BifurcationFeatures:
    """Shape features of every node with exactly two children (module docstring).

    ``pos (N, 3)`` (x, y, z; only x and z are used) or ``(N, 2)`` (x, z), metres."""
    from .skeleton2d import children_lists
    parents = np.asarray(parents)
    pos = np.asarray(pos, np.float64)
    p2 = pos[:, [0, 2]] if pos.shape[1] == 3 else pos
    ch = children_lists(parents)
    up, down = anchor_links(parents)
    apex = np.array([n for n in range(len(parents)) if len(ch[n]) == 2 and up[n] >= 0], int)
    if len(apex) == 0:
        z = np.zeros((0, 3))
        return BifurcationFeatures(apex, apex.copy(), np.zeros((0, 2), int), z, z.copy(), z.copy(),
                                   np.zeros(0, bool))
    root = up[apex]
    kids = np.array([[down[ch[n][0]], down[ch[n][1]]] for n in apex])
    back = p2[root] - p2[apex]
    theta, cont_first, mirrored = canonical_angles(back, p2[kids[:, 0]] - p2[apex], p2[kids[:, 1]] - p2[apex])
    kids = np.where(cont_first[:, None], kids, kids[:, ::-1])
    chord = np.stack([np.linalg.norm(back, axis=1), np.linalg.norm(p2[kids[:, 0]] - p2[apex], axis=1),
                      np.linalg.norm(p2[kids[:, 1]] - p2[apex], axis=1)], axis=1)
    lengths = chord / np.maximum(chord.sum(axis=1, keepdims=True), 1e-12)
    return BifurcationFeatures(apex, root, kids, theta / (2 * np.pi), lengths, chord, mirrored)


def node_rotations(parents: np.ndarray, nodes3d: np.ndarray) -> np.ndarray:
    """``(F, N, 3)`` rotation vectors (radians, world axes) of every node's bone relative to its
    parent bone, frame 0 = rest (zero); the root row is zero. ``nodes3d (F, N, 3)`` metres."""
    from .bones import bone_edges, bone_parents, quat_conj, quat_mul, world_rotations
    parents = np.asarray(parents)
    qw = world_rotations(parents, nodes3d)                        # (F, B, 4)
    pb = bone_parents(parents)
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    qp = np.where((pb >= 0)[None, :, None], qw[:, np.maximum(pb, 0)], ident)
    local = quat_mul(quat_conj(qp), qw)
    out = np.zeros(nodes3d.shape[:2] + (3,))
    out[:, bone_edges(parents)[:, 1]] = quat_log(local)
    return out


def quat_log(q: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` (w, x, y, z) → rotation vectors ``(..., 3)`` (radians),
    angle in [0, π]."""
    q = np.where(q[..., :1] < 0, -q, q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    ang = 2.0 * np.arctan2(s, q[..., 0])
    scale = np.where(s > 1e-12, ang / np.maximum(s, 1e-12), 2.0)
    return v * scale[..., None]


def quat_exp(w: np.ndarray) -> np.ndarray:
    """Rotation vectors ``(..., 3)`` (radians) → unit quaternions ``(..., 4)``."""
    th = np.linalg.norm(w, axis=-1, keepdims=True)
    half = 0.5 * th
    k = np.where(th > 1e-12, np.sin(half) / np.maximum(th, 1e-12), 0.5)
    return np.concatenate([np.cos(half), w * k], axis=-1)


def node_depths(parents: np.ndarray) -> np.ndarray:
    """``(N,)`` edges from the root to each node."""
    from .skeleton2d import topological_order
    parents = np.asarray(parents)
    d = np.zeros(len(parents), int)
    for n in topological_order(parents):
        if parents[n] >= 0:
            d[n] = d[parents[n]] + 1
    return d


def n_kept_bins(n_frames: int, keep: float = KEEP_FRACTION) -> int:
    """K: how many of the ``n_frames // 2`` non-DC rfft bins are kept (at least 2)."""
    return int(max(2, min(n_frames // 2, round(keep * (n_frames // 2)))))


@dataclass
class SpectralFeatures:
    """Motion features of one tree for one axis, over the ``M`` nodes that move:
    ``energy (M, K)`` energy ratios ``|X_k|² / Σ|X|²``; ``u, v (M, K)`` real and imaginary parts
    (phase-aligned, L1 size 1); ``rms (M,)`` radians — the rotation's RMS over the kept bins;
    ``rho (M,)`` normalized depth of the node; ``nodes (M,)`` ids; ``freqs_hz (K,)``;
    ``phase_spread`` radians (circular std of the node phases at the dominant bin)."""

    energy: np.ndarray
    u: np.ndarray
    v: np.ndarray
    rms: np.ndarray
    rho: np.ndarray
    nodes: np.ndarray
    freqs_hz: np.ndarray
    phase_spread: float


def spectra(rot: np.ndarray, keep: float = KEEP_FRACTION) -> np.ndarray:
    """``(K, N, 3)`` complex rfft bins ``1..K`` of ``rot (F, N, 3)`` minus its time mean."""
    F = rot.shape[0]
    X = np.fft.rfft(rot - rot.mean(axis=0, keepdims=True), axis=0)
    return X[1:n_kept_bins(F, keep) + 1]


def spectral_features(parents: np.ndarray, rot: np.ndarray, fps: float,
                      keep: float = KEEP_FRACTION) -> list[SpectralFeatures]:
    """One :class:`SpectralFeatures` per axis from node rotations ``rot (F, N, 3)`` (radians).

    ``rms = sqrt(2 Σ_k |X_k|²) / F`` (Parseval: the RMS of the signal made of the kept bins)."""
    F = rot.shape[0]
    X = spectra(rot, keep)                                        # (K, N, 3)
    K = X.shape[0]
    freqs = np.arange(1, K + 1) * fps / F
    depth = node_depths(parents)
    rho_all = depth / max(int(depth.max()), 1)
    out = []
    for a in range(3):
        Xa = X[:, :, a].T                                         # (N, K)
        P = np.abs(Xa) ** 2
        E = P.sum(1)
        S = np.abs(Xa.real).sum(1) + np.abs(Xa.imag).sum(1)
        ok = (S > 1e-12) & (np.asarray(parents) >= 0)
        Xa, P, E, S, nodes = Xa[ok], P[ok], E[ok], S[ok], np.flatnonzero(ok)
        kdom = np.argmax(P, axis=1)
        al = Xa * np.exp(-1j * np.angle(Xa[np.arange(len(Xa)), kdom]))[:, None]
        kstar = int(np.argmax((P / E[:, None]).mean(0))) if len(P) else 0
        zk = Xa[:, kstar] if len(Xa) else np.zeros(0, complex)
        w = np.abs(zk)
        R = float(np.abs(np.sum(zk)) / max(w.sum(), 1e-300)) if len(zk) else 1.0
        spread = float(np.sqrt(-2.0 * np.log(min(max(R, 1e-12), 1.0))))
        out.append(SpectralFeatures(P / E[:, None], al.real / S[:, None], al.imag / S[:, None],
                                    np.sqrt(2.0 * E) / F, rho_all[nodes], nodes, freqs, spread))
    return out


def energy_spectrum(tree, keep: float = KEEP_FRACTION) -> tuple[np.ndarray, np.ndarray]:
    """``(freqs_hz (K,), E (3, K))``: per rotation axis the energy ratios ``|X_k|² / Σ|X|²``
    averaged over the moving nodes (every node counts equally) of a :class:`~.tree3d.Tree3D`."""
    rot = node_rotations(tree.parents, np.asarray(tree.nodes3d, np.float64))
    sfs = spectral_features(tree.parents, rot, tree.fps, keep)
    E = np.array([sf.energy.mean(0) if len(sf.energy) else np.zeros(len(sf.freqs_hz)) for sf in sfs])
    return sfs[0].freqs_hz, E


def spectrum_peaks(e: np.ndarray, n_peaks: int = 2) -> np.ndarray:
    """Indices ``(n_peaks,)`` (ascending) of the ``n_peaks`` highest local maxima of ``e (K,)``
    (an end bin counts when it is above its one neighbour); fewer maxima repeat the highest."""
    r = np.concatenate([[-np.inf], e, [-np.inf]])
    lm = np.flatnonzero((r[1:-1] >= r[:-2]) & (r[1:-1] >= r[2:]))
    top = lm[np.argsort(e[lm])[::-1][:n_peaks]]
    top = np.concatenate([top, np.repeat(top[:1], n_peaks - len(top))])
    return np.sort(top)


def dominant_frequencies(tree, n_peaks: int = 2, keep: float = KEEP_FRACTION) -> np.ndarray:
    """``(3, n_peaks)`` Hz per rotation axis: the ``n_peaks`` highest peaks (ascending frequency)
    of the tree's mean energy-ratio spectrum (:func:`energy_spectrum`) — e.g. the slow gust and
    the branch sway of the examples."""
    freqs, E = energy_spectrum(tree, keep)
    return np.array([freqs[spectrum_peaks(e, n_peaks)] for e in E])


def shift_tuple(u: np.ndarray) -> np.ndarray:
    """``u (M, K)`` with |u| ≤ 1 and Σu ≤ 1 → ``z (M, K+1)`` = ⟨u + 1, 1 − Σu⟩ / (K + 1), sums to 1."""
    K = u.shape[1]
    return np.concatenate([u + 1.0, 1.0 - u.sum(1, keepdims=True)], axis=1) / (K + 1)


def unshift_tuple(z: np.ndarray) -> np.ndarray:
    """Inverse of :func:`shift_tuple`: ``u_k = (K + 1) z_k − 1`` for the first K components."""
    K = z.shape[1] - 1
    return (K + 1) * z[:, :K] - 1.0


# ============================================================================ species model

@dataclass
class AxisMotion:
    """Motion model for one rotation axis. ``energy`` Dirichlet α ``(K,)`` of the energy ratios
    (which frequencies dominate); ``real`` / ``imag`` Dirichlet α ``(K+1,)`` of the shifted
    real/imaginary tuples (the phases between the bins); ``freqs_hz (K,)`` of the kept bins;
    ``log_rms = (a, b, σ)``: ``log rms ~ N(a + b·ρ, σ²)`` (rms radians, ρ the node's normalized
    depth); ``phase_spread`` radians (circular std of the node phases at the dominant bin)."""

    energy: np.ndarray
    real: np.ndarray
    imag: np.ndarray
    freqs_hz: np.ndarray
    log_rms: tuple
    phase_spread: float
    fallback: str | None = None

    @property
    def dominant_hz(self) -> float:
        """Frequency (Hz) of the largest mean energy ratio."""
        return float(self.freqs_hz[int(np.argmax(self.energy))])

    def peaks_hz(self, n_peaks: int = 2) -> np.ndarray:
        """The ``n_peaks`` highest peaks (Hz, ascending) of the mean energy ratios."""
        return self.freqs_hz[spectrum_peaks(self.energy / self.energy.sum(), n_peaks)]


@dataclass
class SpeciesModel:
    """Everything needed to grow and animate trees like one example (paper §5).

    ``angles``/``lengths``: Dirichlet α ``(3,)`` of ⟨θ1:θ2:θ3⟩ and ⟨L1:L2:L3⟩; ``motion``: one
    :class:`AxisMotion` per axis x, y, z; ``trunk_frac``: trunk (base → first bifurcation) as a
    share of the height; ``segment_frac``: median bone length as a share of the height (how finely
    branches are subdivided); ``segments_per_branch`` median; ``min_branch_frac`` 5th-percentile
    branch chord / height (growth stops below it); ``branch_frac`` median branch chord / height
    (the scale of the first branches above the trunk); ``n_bifurcations`` in the source;
    ``orientation_deg = (mean, std)`` of the branches' angle from the vertical in the picture
    plane (branch chords above the trunk; growth uses it as a tropism term); ``mirror_p`` share
    of clockwise (mirrored) bifurcations;
    ``source_height_m``; ``fps`` and ``n_frames`` of the source; ``conifer``; ``mu_deg`` mean
    branching angle of the source lift; ``fallbacks`` notes from degenerate fits; ``leaves`` the
    source's foliage (median leaf colour sRGB, cluster radius / height, cards per cluster,
    clusters per thin-branch node) or None for a bare source."""

    name: str
    angles: np.ndarray
    lengths: np.ndarray
    motion: list
    trunk_frac: float
    segment_frac: float
    segments_per_branch: float
    min_branch_frac: float
    branch_frac: float
    n_bifurcations: int
    orientation_deg: tuple
    mirror_p: float
    source_height_m: float
    fps: float
    n_frames: int
    conifer: bool = False
    mu_deg: float = 38.0
    version: int = VERSION
    fallbacks: list = field(default_factory=list)
    leaves: dict | None = None      # {"colour": sRGB (3,), "radius_frac", "cards", "per_node"} or None

    def to_json(self) -> dict:
        """JSON-able dict (rounded, human-readable)."""
        def arr(a, d=6):
            return [float(f"{x:.{d}g}") for x in np.asarray(a, float)]
        return {
            "format": FORMAT, "version": VERSION, "name": self.name,
            "conifer": bool(self.conifer),
            "shape": {"angle_alpha": arr(self.angles), "length_alpha": arr(self.lengths),
                      "trunk_frac": round(float(self.trunk_frac), 5),
                      "segment_frac": round(float(self.segment_frac), 5),
                      "segments_per_branch": round(float(self.segments_per_branch), 3),
                      "min_branch_frac": round(float(self.min_branch_frac), 5),
                      "branch_frac": round(float(self.branch_frac), 5),
                      "orientation_deg": [round(float(x), 3) for x in self.orientation_deg],
                      "mirror_p": round(float(self.mirror_p), 4),
                      "n_bifurcations": int(self.n_bifurcations), "mu_deg": round(float(self.mu_deg), 3)},
            "motion": {AXES[a]: {"freqs_hz": arr(m.freqs_hz, 5), "energy_alpha": arr(m.energy),
                                 "real_alpha": arr(m.real), "imag_alpha": arr(m.imag),
                                 "log_rms": arr(m.log_rms), "phase_spread": round(float(m.phase_spread), 5)}
                       for a, m in enumerate(self.motion)},
            "source": {"height_m": round(float(self.source_height_m), 4), "fps": float(self.fps),
                       "n_frames": int(self.n_frames)},
            "fallbacks": list(self.fallbacks),
            **({"leaves": {"colour": arr(self.leaves["colour"], 4),
                           "radius_frac": round(float(self.leaves["radius_frac"]), 5),
                           "cards": int(self.leaves["cards"]),
                           "per_node": round(float(self.leaves["per_node"]), 4)}} if self.leaves else {}),
        }

    @classmethod
    def from_json(cls, d: dict, where: str = "species file") -> "SpeciesModel":
        """Parse :meth:`to_json` output; :class:`InputError` naming the problem otherwise."""
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise InputError(f"{where} is not a Tree from Video species file (no \"format\": \"{FORMAT}\"); "
                             "pick a .json written by Fit Species")
        ver = d.get("version")
        if not isinstance(ver, int) or ver > VERSION:
            raise InputError(f"{where} has version {ver!r}, newer than this add-on reads ({VERSION}); "
                             "update the add-on")
        if ver < 1:
            raise InputError(f"{where} has an old version {ver!r}; fit the species again from its tree")
        try:
            sh, mo, src = d["shape"], d["motion"], d["source"]

            def alpha(x, n=None):
                a = np.asarray(x, np.float64)
                if a.ndim != 1 or (n and len(a) != n) or len(a) < 2 or not np.all(np.isfinite(a)) or (a <= 0).any():
                    raise ValueError("Dirichlet parameters must be positive numbers")
                return a
            motion = []
            for ax in AXES:
                m = mo[ax]
                freqs = np.asarray(m["freqs_hz"], np.float64)
                K = len(freqs)
                energy = alpha(m["energy_alpha"], K)
                real, imag = alpha(m["real_alpha"], K + 1), alpha(m["imag_alpha"], K + 1)
                lr = tuple(float(x) for x in m["log_rms"])
                if len(lr) != 3 or not all(math.isfinite(x) for x in lr) or not np.all(freqs > 0):
                    raise ValueError("log_rms must be three numbers and frequencies positive")
                motion.append(AxisMotion(energy, real, imag, freqs, lr, float(m["phase_spread"])))
            model = cls(str(d.get("name", "species")), alpha(sh["angle_alpha"], 3), alpha(sh["length_alpha"], 3),
                        motion, float(sh["trunk_frac"]), float(sh["segment_frac"]),
                        float(sh["segments_per_branch"]), float(sh["min_branch_frac"]),
                        float(sh["branch_frac"]), int(sh["n_bifurcations"]),
                        _orientation(sh["orientation_deg"]), float(np.clip(float(sh["mirror_p"]), 0.0, 1.0)), float(src["height_m"]), float(src["fps"]),
                        int(src["n_frames"]), bool(d.get("conifer", False)), float(sh.get("mu_deg", 38.0)),
                        ver, list(d.get("fallbacks", [])), _leaf_info(d.get("leaves")))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{where} is incomplete or damaged ({exc.__class__.__name__}: {exc}); "
                             "fit the species again or pick another file") from None
        if not (0 < model.trunk_frac < 1 and 0 < model.segment_frac < 1 and 0 < model.branch_frac < 1
                and 0 < model.min_branch_frac < 1 and model.fps > 0):
            raise InputError(f"{where} has out-of-range shape numbers; fit the species again")
        return model


def _leaf_info(d) -> dict | None:
    if d is None:
        return None
    colour = [float(c) for c in d["colour"]]
    info = {"colour": colour, "radius_frac": float(d["radius_frac"]), "cards": int(d["cards"]),
            "per_node": float(d["per_node"])}
    if len(colour) != 3 or not all(0 <= c <= 1 for c in colour) or not 0 < info["radius_frac"] < 1 \
            or not 1 <= info["cards"] <= 256 or not info["per_node"] > 0:
        raise ValueError("leaves need colour (3 values 0..1), 0 < radius_frac < 1, cards 1..256, per_node > 0")
    return info


def leaf_info(tree) -> dict | None:
    """The foliage of a reconstructed tree as a species keeps it (see :class:`SpeciesModel`)."""
    lv = getattr(tree, "leaves", None)
    if lv is None or lv.count == 0:
        return None
    H = float(max(np.ptp(tree.nodes3d[0][:, 2]), 1e-6))
    r = np.asarray(tree.radius, np.float64)
    thin = int(np.sum(r < 0.3 * r.max())) or 1
    return {"colour": np.median(lv.colour, axis=0).tolist(), "radius_frac": float(lv.radius / H),
            "cards": int(lv.cards), "per_node": float(lv.count / thin)}


def _orientation(x) -> tuple[float, float]:
    o = tuple(float(v) for v in x)
    if len(o) != 2 or not all(math.isfinite(v) for v in o) or o[1] <= 0:
        raise ValueError("orientation_deg must be [mean, std > 0] degrees")
    return o


def branch_orientations(parents: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """``(M,)`` degrees: angle from the vertical (x, z plane) of every branch chord (anchor →
    next anchor or tip) that does not start at the root (the trunk is excluded)."""
    parents = np.asarray(parents)
    p2 = np.asarray(pos, np.float64)[:, [0, 2]] if pos.shape[1] == 3 else np.asarray(pos, np.float64)
    up, down = anchor_links(parents)
    nodes = np.flatnonzero((down == np.arange(len(parents))) & (parents >= 0) & (up >= 0))
    nodes = nodes[parents[up[nodes]] >= 0]
    v = p2[nodes] - p2[up[nodes]]
    return np.degrees(np.abs(np.arctan2(v[:, 0], v[:, 1])))


def _fit_log_rms(rms: np.ndarray, rho: np.ndarray) -> tuple[float, float, float]:
    """``log rms = a + b ρ + ε`` by least squares; ``(a, b, σ)`` (b = 0 with fewer than 3 nodes;
    σ at least 0.05)."""
    if len(rms) == 0:
        return (math.log(1e-4), 0.0, 0.05)
    y = np.log(rms)
    if len(rms) < 3 or np.ptp(rho) < 1e-9:
        return (float(y.mean()), 0.0, float(max(y.std(), 0.05)))
    A = np.stack([np.ones_like(rho), rho], 1)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    sigma = float(max(np.std(y - A @ coef), 0.05))
    return (float(coef[0]), float(coef[1]), sigma)


def fit_axis_motion(sf: SpectralFeatures) -> AxisMotion:
    """Dirichlets of the energy ratios and of the shifted real/imag tuples, and the RMS model."""
    K = len(sf.freqs_hz)
    if len(sf.u) == 0:
        return AxisMotion(np.ones(K), np.ones(K + 1), np.ones(K + 1), sf.freqs_hz, _fit_log_rms(sf.rms, sf.rho),
                          sf.phase_spread, "no moving node: uniform spectra")
    # energy ratios: mean fixed to the sample mean (so the dominant frequency of the example is
    # exactly the model's), precision by ML; real/imag tuples: full ML
    fe = fit_dirichlet(sf.energy, fixed_mean=sf.energy.mean(axis=0))
    fr, fi = fit_dirichlet(shift_tuple(sf.u)), fit_dirichlet(shift_tuple(sf.v))
    notes = [f"{n}: {f.fallback}" for n, f in (("energy", fe), ("real", fr), ("imag", fi)) if f.fallback]
    return AxisMotion(fe.alpha, fr.alpha, fi.alpha, sf.freqs_hz, _fit_log_rms(sf.rms, sf.rho), sf.phase_spread,
                      "; ".join(notes) or None)


def _orientation_stats(g: np.ndarray) -> tuple[float, float]:
    """(mean, std) degrees, std at least 10°; (40, 30) with fewer than 3 branches."""
    if len(g) < 3:
        return (40.0, 30.0)
    return (float(g.mean()), float(max(g.std(), 10.0)))


def fit_species(tree, name: str, keep: float = KEEP_FRACTION) -> SpeciesModel:
    """Fit a :class:`SpeciesModel` to a :class:`~.tree3d.Tree3D` (metres, frame 0 = rest).

    Raises :class:`InputError` if the tree has no bifurcation or fewer than 8 frames."""
    parents = np.asarray(tree.parents)
    nodes = np.asarray(tree.nodes3d, np.float64)
    if nodes.shape[0] < 8:
        raise InputError(f"the tree has {nodes.shape[0]} frame(s); fitting its motion needs at least 8 — "
                         "reconstruct a longer clip")
    feats = bifurcation_features(parents, nodes[0])
    if len(feats.apex) == 0:
        raise InputError("the tree has no bifurcation to learn from; reconstruct a tree with branches")
    height = float(max(np.ptp(nodes[0, :, 2]), nodes[0, :, 2].max(), 1e-6))
    fa, fl = fit_dirichlet(feats.angles), fit_dirichlet(feats.lengths)
    fallbacks = [f"{n}: {f.fallback}" for n, f in (("angles", fa), ("lengths", fl)) if f.fallback]
    # absolute scale: trunk, bone and branch lengths as shares of the height
    from .skeleton2d import edges_of
    from .skeleton2d import children_lists
    up, down = anchor_links(parents)
    root = int(np.flatnonzero(parents < 0)[0])
    kids0 = children_lists(parents)[root]
    first = int(down[kids0[0]]) if len(kids0) == 1 else root
    trunk = float(np.linalg.norm(nodes[0, first, [0, 2]] - nodes[0, root, [0, 2]]))
    e = edges_of(parents)
    bone = np.linalg.norm(nodes[0, e[:, 1]][:, [0, 2]] - nodes[0, e[:, 0]][:, [0, 2]], axis=1)
    seg_per_branch = []                     # edges between consecutive anchors/tips
    for n in np.flatnonzero((down == np.arange(len(parents))) & (parents >= 0)):
        c, k = n, 0
        while True:
            k += 1
            c = parents[c]
            if down[c] == c:
                break
        seg_per_branch.append(k)
    rot = node_rotations(parents, nodes)
    sfs = spectral_features(parents, rot, tree.fps, keep)
    motion = [fit_axis_motion(sf) for sf in sfs]
    fallbacks += [f"motion {AXES[a]}: {m.fallback}" for a, m in enumerate(motion) if m.fallback]
    return SpeciesModel(
        name=name, angles=fa.alpha, lengths=fl.alpha, motion=motion,
        trunk_frac=float(np.clip(trunk / height, 0.02, 0.9)),
        segment_frac=float(np.clip(np.median(bone) / height, 0.005, 0.5)),
        segments_per_branch=float(np.median(seg_per_branch)) if seg_per_branch else 1.0,
        min_branch_frac=float(np.clip(np.percentile(feats.chord[:, 1:], 5) / height, 0.002, 0.3)),
        branch_frac=float(np.clip(np.median(feats.chord[:, 1:]) / height, 0.005, 0.5)),
        n_bifurcations=int(len(feats.apex)),
        orientation_deg=_orientation_stats(branch_orientations(parents, nodes[0])),
        mirror_p=float(np.mean(feats.mirrored)), source_height_m=height, fps=float(tree.fps),
        n_frames=int(nodes.shape[0]), conifer=bool(tree.meta.get("conifer", False)),
        mu_deg=float(tree.meta.get("mu_deg", 38.0)), fallbacks=fallbacks, leaves=leaf_info(tree))


# ============================================================================ files

def dumps_species(model: SpeciesModel) -> str:
    """Indented JSON with every list of numbers on one line (readable and diffable)."""
    import re
    text = json.dumps(model.to_json(), indent=1, ensure_ascii=False)
    return re.sub(r"\[\s*([-0-9.eE,\s]*?)\s*\]", lambda m: "[" + re.sub(r"\s+", " ", m.group(1)) + "]", text)


def save_species(path: str | os.PathLike, model: SpeciesModel) -> None:
    """Write ``model`` as indented JSON to ``path`` atomically (temporary file + rename)."""
    from .model import publish
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".json", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(dumps_species(model) + "\n")
        publish(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def load_species(path: str | os.PathLike) -> SpeciesModel:
    """Read a species file; :class:`InputError` for a missing, unreadable, foreign, newer or
    damaged file."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"species file '{path}' does not exist; pick a .json from the species library "
                         "or fit one from a reconstructed tree")
    from .jsonio import read_json
    data = read_json(path, f"species file '{path}'", "pick a .json written by Fit Species")
    return SpeciesModel.from_json(data, f"species file '{path}'")


SPECIES_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "species")


def species_library(folder: str | None = None) -> dict[str, str]:
    """``{name: path}`` of the species files shipped with the add-on (``species/*.json``), the
    name being the file name without ``.json``, sorted by name."""
    folder = folder or SPECIES_DIR
    if not os.path.isdir(folder):
        return {}
    names = sorted(f for f in os.listdir(folder) if f.lower().endswith(".json"))
    return {os.path.splitext(f)[0]: os.path.join(folder, f) for f in names}


def model_summary(model: SpeciesModel) -> dict:
    """Small dict for UIs and logs: mean angle/length ratios, dominant frequency per axis."""
    return {"angles_mean": (model.angles / model.angles.sum()).round(3).tolist(),
            "lengths_mean": (model.lengths / model.lengths.sum()).round(3).tolist(),
            "dominant_hz": [round(m.dominant_hz, 3) for m in model.motion],
            "peaks_hz": [m.peaks_hz().round(3).tolist() for m in model.motion],
            "conifer": model.conifer}


__all__ = ["DirichletFit", "fit_dirichlet", "inv_digamma", "dirichlet_loglik", "BifurcationFeatures",
           "bifurcation_features", "node_rotations", "spectral_features", "SpeciesModel", "AxisMotion",
           "fit_species", "save_species", "load_species", "species_library", "model_summary"]
