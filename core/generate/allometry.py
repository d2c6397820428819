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

import math
from dataclasses import dataclass

import numpy as np

from ..topology import children_lists, node_depths, subtree_masks

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


def _rotate(v: np.ndarray, k: np.ndarray, theta) -> np.ndarray:
    """Rodrigues: ``v (..., 3)`` turned by ``theta`` about the unit axis ``k (3,)``."""
    theta = np.asarray(theta, np.float64)[..., None]
    return v * np.cos(theta) + np.cross(k, v) * np.sin(theta) + k * (v @ k)[..., None] * (1 - np.cos(theta))


def _turn_cost(theta: np.ndarray, u1: np.ndarray, u2: np.ndarray, axis: np.ndarray, f: np.ndarray,
               want: tuple[float, float]) -> np.ndarray:
    """How far both children turned by ``theta`` lie from the angles to the father's line ``f`` that
    Holton's rule ``want`` s (radians, summed), plus a thousandth of the turn (the smallest of equals)."""
    g1 = np.arccos(np.clip(_rotate(u1, axis, theta) @ f, -1.0, 1.0))
    g2 = np.arccos(np.clip(_rotate(u2, axis, theta) @ f, -1.0, 1.0))
    return np.abs(g1 - want[0]) + np.abs(g2 - want[1]) + 1e-3 * np.abs(theta)


def holton_pose(parents: np.ndarray, pos: np.ndarray, anchor: np.ndarray, radius: np.ndarray,
                inside=None, gamma: float = 2.0) -> tuple[np.ndarray, dict]:
    """``(pos', info)``: a tree's rest pose ``pos (N, 3)`` with every two-child fork's children
    turned together about the fork (a rigid turn about the normal of their plane, so the angle ``a``
    between them is kept) until the thicker leaves the father's line by ``a · d_2^γ / (d_1^γ +
    d_2^γ)`` and the thinner by the rest of ``a`` (Holton, module docstring), or as near as a turn in
    that plane gets them (the turn is
    searched every degree, then every hundredth of one). Directions are branch chords (fork → the child's next ``anchor``; the
    father's previous anchor → fork). Forks are taken root first, so a turn carries the forks above
    it. With ``inside`` (points ``(P, 3)`` → bool) a turn that would take any node of the subtree out
    of the envelope that was in it is halved, then dropped. ``info``: forks, forks turned, the median turn in degrees."""
    parents = np.asarray(parents)
    pos = np.asarray(pos, np.float64).copy()
    r = np.asarray(radius, np.float64)
    kids = children_lists(parents)
    depth = node_depths(parents)
    fork = sorted((n for n in range(len(parents)) if len(kids[n]) == 2 and parents[n] >= 0), key=lambda n: depth[n])
    if not fork:
        return pos, {"forks": 0, "turned": 0}
    pair = np.array([sorted(kids[n], key=lambda c: -r[c]) for n in fork])      # (F, 2): thicker first
    subs = subtree_masks(parents, pair.T.ravel())
    F = len(fork)
    anchor = np.asarray(anchor, bool)
    grid = np.radians(np.arange(-180.0, 180.0, 1.0))

    def chord_end(c: int) -> int:              # the child's next anchor along its chain
        while not anchor[c] and len(kids[c]) == 1:
            c = kids[c][0]
        return c

    def chord_start(n: int) -> int:            # the father's previous anchor
        p = int(parents[n])
        while p >= 0 and not anchor[p] and parents[p] >= 0:
            p = int(parents[p])
        return max(p, 0)

    def unit(v):
        return v / max(float(np.linalg.norm(v)), 1e-12)

    turns = []
    for i, n in enumerate(fork):
        c1, c2 = int(pair[i, 0]), int(pair[i, 1])
        f = unit(pos[n] - pos[chord_start(n)])
        u1, u2 = unit(pos[chord_end(c1)] - pos[n]), unit(pos[chord_end(c2)] - pos[n])
        axis = np.cross(u1, u2)
        if np.linalg.norm(axis) < 1e-6:                    # children in one line: no plane to turn in
            continue
        axis = unit(axis)
        a = math.acos(float(np.clip(u1 @ u2, -1.0, 1.0)))
        w = r[c2] ** gamma / max(r[c1] ** gamma + r[c2] ** gamma, 1e-300)
        want = (a * w, a * (1.0 - w))
        theta = float(grid[int(np.argmin(_turn_cost(grid, u1, u2, axis, f, want)))])
        fine = theta + np.radians(np.arange(-1.0, 1.0 + 1e-9, 0.01))          # then to a hundredth of one
        theta = float(fine[int(np.argmin(_turn_cost(fine, u1, u2, axis, f, want)))])
        member = subs[i] | subs[F + i]
        for k in (1.0, 0.5, 0.0):
            moved = pos[n] + _rotate(pos[member] - pos[n], axis, k * theta)
            if inside is None or k == 0.0 or not (inside(pos[member]) & ~inside(moved)).any():
                pos[member] = moved
                if k > 0 and theta != 0.0:
                    turns.append(abs(k * theta))
                break
    return pos, {"forks": F, "turned": len(turns),
                 "median_turn_deg": round(float(np.degrees(np.median(turns))), 3) if turns else 0.0}
