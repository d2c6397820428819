"""Motion for a generated tree from a species model's spectra (paper §5.2: sample, inverse FFT).

Per node ``i`` and rotation axis ``a`` (world x, y, z; radians, relative to the parent bone):

    e ~ Dir(α_energy)            energy ratios over the K kept frequencies f_k (Hz)
    u, v from Dir(α_real), Dir(α_imag), the shift removed: u_k = (K+1) z_k − 1   (features.unshift_tuple)
    ψ_k = atan2(v_k, u_k)        phase of bin k relative to the node's dominant bin
    rms ~ exp(N(a + b ρ_i, σ²))  (ρ normalized depth; clipped to ±2.5 σ and to the source's largest)
    φ_i = Φ_a + N(0, spread²)    node phase: one tree phase per axis plus the example's spread
    ω_a(t) = Σ_k √2 · rms · √e_k · cos(2π f_k (t + t0) + ψ_k + φ_i)

— the inverse Fourier transform of the sampled spectrum, evaluated at the scene's frame times
(``t = n / fps``, so another clip length or frame rate keeps the frequencies in Hz). Its RMS over
time is ``rms`` (Σ e = 1). The component along the bone (a twist, which a swing-only skeleton
never shows) is removed. Then ``ω(t) · g(t)`` (wind × audio, :mod:`.wind`) and forward
kinematics: ``q_i = q_parent ⊗ exp(ω_i)``, ``x_i = x_parent + R(q_i)(x_i⁰ − x_parent⁰)`` — bone
lengths stay exact and node 0 stays at the origin.
"""
from __future__ import annotations

import numpy as np

from ..rotations import quat_exp, quat_mul, quat_rotate
from ..topology import node_depths
from .features import unshift_tuple
from .species import AxisMotion, SpeciesModel


def whole_periods(freqs_hz: np.ndarray, period_s: float) -> np.ndarray:
    """``freqs_hz`` moved to the nearest multiple (≥ 1) of ``1 / period_s``: every component then
    repeats after ``period_s`` seconds, and so does their sum (a loop by construction)."""
    return np.maximum(np.round(np.asarray(freqs_hz, np.float64) * period_s), 1.0) / period_s


def sample_axis(m: AxisMotion, rho: np.ndarray, t: np.ndarray, rng: np.random.Generator,
                tree_phase: float, period_s: float | None = None) -> np.ndarray:
    """``(F, M)`` rotation (radians) about one axis for ``M`` nodes of normalized depth ``rho
    (M,)`` at times ``t (F,)`` seconds (module docstring); with ``period_s`` the frequencies on
    whole periods of it (:func:`whole_periods`)."""
    M = len(rho)
    e = rng.dirichlet(m.energy, size=M)
    e = np.where(np.isfinite(e), np.maximum(e, 0.0), 0.0)
    e /= np.maximum(e.sum(1, keepdims=True), 1e-300)
    u = unshift_tuple(rng.dirichlet(m.real, size=M))
    v = unshift_tuple(rng.dirichlet(m.imag, size=M))
    psi = np.arctan2(v, u)                                       # (M, K)
    a, b, sig = m.log_rms
    rms = np.exp(a + b * rho + sig * np.clip(rng.standard_normal(M), -2.5, 2.5))
    if m.rms_max is not None:                                    # never beyond the source's bones
        rms = np.minimum(rms, m.rms_max)
    phi = tree_phase + m.phase_spread * rng.standard_normal(M)
    amp = np.sqrt(2.0) * rms[:, None] * np.sqrt(e)               # (M, K)
    theta = psi + phi[:, None]
    freqs = m.freqs_hz if period_s is None else whole_periods(m.freqs_hz, period_s)
    arg = 2 * np.pi * np.outer(t, freqs)                         # (F, K)
    return np.cos(arg) @ (amp * np.cos(theta)).T - np.sin(arg) @ (amp * np.sin(theta)).T
    # cos(x + θ) = cos x cos θ − sin x sin θ, summed over k as two (F, K) @ (K, M) products


def sample_rotations(model: SpeciesModel, parents: np.ndarray, rest: np.ndarray, n_frames: int, fps: float,
                     rng: np.random.Generator, time_offset_s: float = 0.0,
                     tree_phase: np.ndarray | None = None, period_s: float | None = None) -> np.ndarray:
    """``(F, N, 3)`` local rotation vectors (radians) for every node (root row zero), twist
    along each bone removed. ``rest (N, 3)`` metres; ``tree_phase (3,)`` radians (random if None);
    ``period_s``: the sway repeats after it exactly (frequencies on whole periods)."""
    parents = np.asarray(parents)
    N = len(parents)
    depth = node_depths(parents)
    rho = depth / max(int(depth.max()), 1)
    t = np.arange(n_frames) / float(fps) + float(time_offset_s)
    if tree_phase is None:
        tree_phase = rng.uniform(0.0, 2 * np.pi, 3)
    moving = np.flatnonzero(parents >= 0)
    w = np.zeros((n_frames, N, 3))
    for a in range(3):
        w[:, moving, a] = sample_axis(model.motion[a], rho[moving], t, rng, float(tree_phase[a]), period_s)
    d = np.zeros((N, 3))
    d[moving] = rest[moving] - rest[parents[moving]]
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    w -= np.sum(w * d[None], axis=2, keepdims=True) * d[None]   # no twist about the bone
    return w


def forward_kinematics(parents: np.ndarray, rest: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Node positions ``(F, N, 3)`` from ``rest (N, 3)`` and local rotation vectors ``rot (F, N, 3)``:
    root to tip by depth, ``q_i = q_parent ⊗ exp(ω_i)`` and ``x_i = x_p + R(q_i)(x_i⁰ − x_p⁰)``
    (vectorised over frames and the nodes of one depth)."""
    parents = np.asarray(parents)
    F, N = rot.shape[:2]
    depth = node_depths(parents)
    q = np.zeros((F, N, 4))
    q[..., 0] = 1.0
    X = np.repeat(np.asarray(rest, np.float64)[None], F, axis=0)
    qloc = quat_exp(rot)
    for d in range(1, int(depth.max()) + 1 if N else 1):
        idx = np.flatnonzero(depth == d)
        p = parents[idx]
        qi = quat_mul(q[:, p], qloc[:, idx])
        qi /= np.linalg.norm(qi, axis=-1, keepdims=True)
        q[:, idx] = qi
        X[:, idx] = X[:, p] + quat_rotate(qi, (rest[idx] - rest[p])[None])
    return X
