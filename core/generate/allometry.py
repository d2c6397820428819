"""Allometry checked per fork (issue 36 part 3; seed 001 §4.4, after Holton 1994 and Leonardo's rule).

At a fork of father diameter ``d`` and children ``d_1 ≥ d_2`` (the two thickest children) leaving at
angles ``a_1``, ``a_2`` from the father's direction (``a = a_1 + a_2`` between them):

* **pipe model** (Leonardo's rule at γ = 2): ``d^Δ = Σ_i d_i^Δ``; the fork's exponent Δ is solved
  per fork (bisection: ``Σ (d_i / d)^Δ`` falls from k at Δ = 0 to 0), the tree's is their median.
  A fork whose child is as thick as its father has no finite Δ and is counted apart.
* **Holton's angles** (seed 001 eq. 1–2, ``d_2 = sqrt(a_1 / a) d``: a child leaves the father's line
  by the share of the strands the *other* child carries):

      a_1 = a · d_2^γ / (d_1^γ + d_2^γ),   γ = Δ (2 for Leonardo)

  the thicker child bends less. The fit is the median of ``|a_1 − a · d_2^γ / (d_1^γ + d_2^γ)|``
  over the forks, degrees.

:func:`allometry_report` is what a tree's ``meta["allometry"]`` holds; with a species it also
compares the tree's mean branching angle with the species' (``mu_deg``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: a fork's exponent is searched in this range
EXPONENT_RANGE = (0.5, 8.0)


@dataclass
class Forks:
    """The forks of a tree: ``node (F,)`` the fork nodes, ``d (F,)`` father diameters, ``d1``,
    ``d2 (F,)`` the two thickest children's diameters (``d1 ≥ d2``), ``children (F, K)`` every
    child's diameter, thickest first, padded with 0, ``a1``, ``a2 (F,)`` the two children's angles from the father's
    direction, radians."""

    node: np.ndarray
    d: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    children: np.ndarray
    a1: np.ndarray
    a2: np.ndarray


def forks(parents: np.ndarray, pos: np.ndarray, radius: np.ndarray) -> Forks:
    """Every node with two or more children and a parent (:class:`Forks`) of a tree whose rest
    nodes are ``pos (N, 3)`` and radii ``radius (N,)`` (any one unit)."""
    parents = np.asarray(parents)
    pos = np.asarray(pos, np.float64)
    r = np.asarray(radius, np.float64)
    child = np.flatnonzero(parents >= 0)
    counts = np.bincount(parents[child], minlength=len(parents))
    node = np.flatnonzero((counts >= 2) & (parents >= 0))
    if len(node) == 0:
        z = np.zeros(0)
        return Forks(node, z, z, z, np.zeros((0, 2)), z, z)
    # children of each fork, thickest first, padded (K = most children)
    kid = child[np.isin(parents[child], node)]
    order = np.lexsort((-r[kid], parents[kid]))
    kid = kid[order]
    row = np.searchsorted(node, parents[kid])                    # sorted: kid is ordered by parent
    start = np.searchsorted(row, np.arange(len(node)))
    col = np.arange(len(kid)) - start[row]
    K = int(col.max()) + 1
    dia = np.zeros((len(node), K))
    dia[row, col] = 2.0 * r[kid]
    ids = np.full((len(node), K), -1)
    ids[row, col] = kid
    father = pos[node] - pos[parents[node]]
    father /= np.maximum(np.linalg.norm(father, axis=1, keepdims=True), 1e-12)

    def angle(c):
        v = pos[c] - pos[node]
        v /= np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
        return np.arccos(np.clip((v * father).sum(1), -1.0, 1.0))
    return Forks(node, 2.0 * r[node], dia[:, 0], dia[:, 1], dia, angle(ids[:, 0]), angle(ids[:, 1]))


def fork_exponents(f: Forks) -> np.ndarray:
    """``(F,)`` each fork's pipe exponent Δ (``d^Δ = Σ d_i^Δ``), NaN where a child is as thick as
    its father (no finite Δ) or a diameter is 0."""
    ratio = f.children / np.maximum(f.d, 1e-300)[:, None]                # (F, K), 0 for padding
    ok = (f.d > 0) & (f.d2 > 0) & (ratio.max(1) < 1.0)
    lo = np.full(len(f.d), EXPONENT_RANGE[0])
    hi = np.full(len(f.d), EXPONENT_RANGE[1])
    safe = np.where(ratio > 0, ratio, 1.0)
    for _ in range(60):                                  # Σ ratio^Δ − 1 falls with Δ
        mid = 0.5 * (lo + hi)
        s = np.where(ratio > 0, safe ** mid[:, None], 0.0).sum(1) - 1.0
        lo = np.where(s > 0, mid, lo)
        hi = np.where(s > 0, hi, mid)
    return np.where(ok, 0.5 * (lo + hi), np.nan)


def holton_a1(a: np.ndarray, d1: np.ndarray, d2: np.ndarray, gamma: float = 2.0) -> np.ndarray:
    """The thicker child's angle from the father's line Holton's rule gives (module docstring)."""
    w = d2 ** gamma / np.maximum(d1 ** gamma + d2 ** gamma, 1e-300)
    return a * w


def allometry_report(parents: np.ndarray, pos: np.ndarray, radius: np.ndarray, mu_deg: float | None = None) -> dict:
    """``{forks, pipe_exponent, pipe_exponent_iqr, no_exponent, leonardo_residual, holton_error_deg,
    branch_angle_deg, species_mu_deg}`` of a tree (module docstring; ``leonardo_residual`` the median
    ``|d² − Σ d_i²| / d²``, ``branch_angle_deg`` the mean of the two children's angles, with
    ``mu_deg`` the species' mean branching angle beside it)."""
    f = forks(parents, pos, radius)
    out: dict = {"forks": int(len(f.node))}
    if len(f.node) == 0:
        return out
    e = fork_exponents(f)
    good = np.isfinite(e)
    out["no_exponent"] = int((~good).sum())
    if good.any():
        q1, med, q3 = np.percentile(e[good], [25, 50, 75])
        out["pipe_exponent"] = round(float(med), 4)
        out["pipe_exponent_iqr"] = [round(float(q1), 4), round(float(q3), 4)]
    leo = np.abs(f.d ** 2 - (f.children ** 2).sum(1)) / np.maximum(f.d ** 2, 1e-300)
    out["leonardo_residual"] = round(float(np.median(leo)), 4)
    gamma = float(np.median(e[good])) if good.any() else 2.0
    a = f.a1 + f.a2
    err = np.abs(f.a1 - holton_a1(a, f.d1, f.d2, gamma))
    out["holton_error_deg"] = round(float(np.degrees(np.median(err))), 3)
    out["branch_angle_deg"] = round(float(np.degrees(np.mean(np.concatenate([f.a1, f.a2])))), 3)
    if mu_deg is not None:
        out["species_mu_deg"] = round(float(mu_deg), 3)
    return out
