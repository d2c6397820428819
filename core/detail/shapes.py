"""Small shape and motion details (paper §3.3, Appendix B.2; Flash–Hogan; bark from seed 004).

* :func:`minimum_jerk` — the Flash & Hogan (1985) minimum-jerk profile
  ``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵``: s(0) = 0, s(1) = 1, zero velocity and acceleration at both ends;
  :func:`curly_branch` bends a straight segment by a bounded lateral offset along that profile.
* :func:`bark_radius` — ``r(θ) = r0 + Σ_i b_i sin(ω_i θ + φ_i)`` with integer ω_i, so every
  ring closes seamlessly (r(0) = r(2π)); amplitudes as shares of r0 (smooth ≤ 0.5 %, rough 1–5 %).
* :func:`flutter` — a leaf cluster's extra rotation ``y(t) = A sin(ωt + β)`` with the amplitude
  modulated by its branch's speed and the phase β from its distance to its node.
"""
from __future__ import annotations

import numpy as np

BARK_PRESETS = {"smooth": (0.0, 0.005), "rough": (0.01, 0.05)}   # amplitude range, share of r0


def minimum_jerk(tau: np.ndarray) -> np.ndarray:
    """``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` for τ in [0, 1] (Flash & Hogan)."""
    tau = np.clip(np.asarray(tau, float), 0.0, 1.0)
    return tau ** 3 * (10 - 15 * tau + 6 * tau ** 2)


def curly_branch(a: np.ndarray, b: np.ndarray, offset: np.ndarray, n: int = 9) -> np.ndarray:
    """Points ``(n, 3)`` from ``a`` to ``b`` bending out by ``offset (3,)`` at the middle: the
    lateral offset follows ``4·s(τ)(1 − s(τ))``-shaped minimum-jerk easing, so the curve leaves
    and reaches both ends along the straight segment (zero lateral velocity there)."""
    tau = np.linspace(0.0, 1.0, n)
    s = minimum_jerk(tau)
    bump = 4.0 * s * (1.0 - s)                   # 0 at both ends, 1 in the middle
    return a[None] + (b - a)[None] * tau[:, None] + offset[None] * bump[:, None]


def bark_radius(theta: np.ndarray, r0: float, amplitudes: np.ndarray, freqs: np.ndarray,
                phases: np.ndarray) -> np.ndarray:
    """``r(θ) = r0 (1 + Σ_i b_i sin(ω_i θ + φ_i))`` with integer ``freqs`` ω_i (closes at 2π);
    ``amplitudes`` b_i are shares of r0."""
    freqs = np.asarray(freqs)
    if not np.all(freqs == np.round(freqs)):
        raise ValueError("bark frequencies must be integers, or the ring would not close")
    theta = np.asarray(theta, float)[..., None]
    return r0 * (1.0 + np.sum(amplitudes * np.sin(freqs * theta + phases), axis=-1))


def random_bark(kind: str, n_terms: int = 4, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(amplitudes, integer frequencies, phases) for a bark preset ("smooth" or "rough"); the
    amplitudes sum to at most the preset's maximum share of the radius."""
    lo, hi = BARK_PRESETS[kind]
    rng = np.random.default_rng(seed)
    amp = rng.uniform(lo, hi, n_terms) / n_terms
    freqs = rng.integers(3, 13, n_terms)
    return amp, freqs, rng.uniform(0, 2 * np.pi, n_terms)


def flutter(t: np.ndarray, branch_speed: np.ndarray, omega: float, beta: float | np.ndarray,
            gain: float) -> np.ndarray:
    """``y(t) = A(t) sin(ω t + β)`` radians, ``A(t) = gain · |branch speed(t)|`` (Appendix B.2):
    ``t (F,)`` seconds, ``branch_speed (F,)`` in units/s, ``omega`` rad/s, ``beta`` rad."""
    return gain * np.abs(branch_speed) * np.sin(omega * np.asarray(t, float) + beta)
