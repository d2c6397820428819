"""The features of the species model (paper §5.1–5.2), measured on a reconstructed tree.

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

Each tuple set gets a Dirichlet fitted by maximum likelihood (:func:`.dirichlet.fit_dirichlet`,
Minka 2003); :class:`.species.SpeciesModel` holds them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..rotations import quat_log
from ..topology import node_depths

KEEP_FRACTION = 0.2              # lowest share of the frequency bins kept as "dominant"


# ============================================================================ features

def anchor_links(parents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``up (N,)``: nearest strict ancestor that is an anchor (root or branch point; −1 for the
    root); ``down (N,)``: for every node, the first anchor or tip at or below it along single-child
    chains (the node itself if it is a branch point or a tip)."""
    from ..topology import children_lists, topological_order
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
    from ..topology import children_lists
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
    from ..bones import bone_edges, bone_parents, world_rotations
    from ..rotations import quat_conj, quat_mul
    parents = np.asarray(parents)
    qw = world_rotations(parents, nodes3d)                        # (F, B, 4)
    pb = bone_parents(parents)
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    qp = np.where((pb >= 0)[None, :, None], qw[:, np.maximum(pb, 0)], ident)
    local = quat_mul(quat_conj(qp), qw)
    out = np.zeros(nodes3d.shape[:2] + (3,))
    out[:, bone_edges(parents)[:, 1]] = quat_log(local)
    return out


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
