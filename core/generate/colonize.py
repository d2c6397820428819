"""Space colonization (Runions, Lane, Prusinkiewicz 2007) in a 2D crown: branches grown toward
attraction points spread over a region, each point removed once a branch reaches it.

Each round, every attraction point ``a`` in reach (distance < ``influence``) pulls its nearest
node ``v``; a pulled node grows one new node

    v' = v + D · n̂,   n = Σ_a (a − v) / |a − v| + w_up · ẑ        (Runions et al., Eq. 1, plus tropism)

(``D`` the step, ``w_up`` an upward pull), and every point closer than ``kill`` to a node is removed.
While no point is in reach, the node nearest to one grows toward it (a trunk
below a crown that starts higher up). Growth ends when every point is taken, no node can grow or
the node budget is spent. Branches cannot
come closer than ``kill`` to a point another branch has already taken, so they fill the crown
without crossing back over each other (the generator's pair growth, :func:`.growth.grow_2d`,
measured in a crown's picture plane, crosses itself; tests/test_limbs.py prints both).

Units are whatever the caller's (the limbs use image pixels, z up), in 2D ``(x, z)`` or 3D
``(x, y, z)``: the upward pull is along the last axis. Vectorized per round.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..topology import without_nodes


@dataclass
class Colonized:
    """``parents (N,)`` (-1 for node 0), ``pos (N, 2)`` (x, z) or ``(N, 3)`` (x, y, z); ``rounds`` growth rounds run;
    ``stopped`` why growth ended; ``left`` attraction points never reached."""

    parents: np.ndarray
    pos: np.ndarray
    rounds: int
    stopped: str
    left: int


def colonize(start_parents: np.ndarray, start_pos: np.ndarray, growing: np.ndarray, points: np.ndarray,
             step: float, influence: float, kill: float, up: float = 0.0, budget: int = 400,
             max_rounds: int = 400, inside: Callable[[np.ndarray], np.ndarray] | None = None) -> Colonized:
    """Grow from the tree ``start_parents (K,)``, ``start_pos (K, 2 or 3)`` (its nodes with
    ``growing (K,)`` True may sprout; every new node may) toward ``points (M, 2 or 3)``; see the
    module docstring for ``step`` D, ``influence``, ``kill`` and ``up`` (w_up). At most ``budget``
    nodes. ``inside``: ``(L, 2 or 3) → (L,)`` bool, the region; a node whose next step leaves it
    stops (a branch does not cut across a notch of the crown)."""
    par = list(np.asarray(start_parents, np.int64))
    pos = np.asarray(start_pos, np.float64).copy()
    can = np.asarray(growing, bool).copy()
    pts = np.asarray(points, np.float64)
    alive = np.ones(len(pts), bool)
    if len(pos):
        alive &= cKDTree(pos).query(pts, distance_upper_bound=kill)[0] > kill
    stopped = "round limit reached"
    rounds = 0
    while rounds < max_rounds:
        rounds += 1
        if len(pos) >= budget:
            stopped = "node budget reached"
            break
        live = np.flatnonzero(can)
        if not alive.any() or len(live) == 0:
            stopped = "crown filled" if not alive.any() else "no node can grow"
            break
        a = pts[alive]
        d, j = cKDTree(pos[live]).query(a, distance_upper_bound=influence)
        ok = np.isfinite(d)
        if not ok.any():                 # nothing in reach: the node nearest the crown grows toward it
            d, j = cKDTree(pos[live]).query(a)
            ok = np.arange(len(a)) == int(np.argmin(d))
        node = live[j[ok]]
        unit = (a[ok] - pos[node]) / np.maximum(d[ok], 1e-12)[:, None]
        pull = np.zeros_like(pos)
        np.add.at(pull, node, unit)
        growers = np.unique(node)
        n = pull[growers]
        n[:, -1] += up                          # up: the last axis (z in (x, z) and in (x, y, z))
        norm = np.linalg.norm(n, axis=1)
        keep = norm > 1e-9                      # pulled equally both ways: that node rests this round
        growers, n, norm = growers[keep], n[keep], norm[keep]
        if len(growers) == 0:
            stopped = "no node can grow"
            break
        growers, n, norm = growers[:budget - len(pos)], n[:budget - len(pos)], norm[:budget - len(pos)]
        new = pos[growers] + step * n / norm[:, None]
        # a grower whose new node would sit on an existing one (two points tugging it back and
        # forth) or leave the region stops; the others add theirs
        dup = cKDTree(pos).query(new)[0] < 0.25 * step
        if inside is not None:
            dup |= ~np.asarray(inside(0.5 * (pos[growers] + new)), bool) | ~np.asarray(inside(new), bool)
        can[growers[dup]] = False
        growers, new = growers[~dup], new[~dup]
        if len(growers) == 0:
            continue
        par.extend(int(g) for g in growers)
        pos = np.vstack([pos, new])
        can = np.concatenate([can, np.ones(len(new), bool)])
        hit = cKDTree(new).query(pts, distance_upper_bound=kill)[0] < kill
        alive &= ~hit
    return Colonized(np.asarray(par, np.int64), pos, rounds, stopped, int(alive.sum()))


def prune_stubs(parents: np.ndarray, pos: np.ndarray, min_len: float) -> tuple[np.ndarray, np.ndarray]:
    """Remove terminal branches (tip back to the nearest fork) shorter than ``min_len``; node 0
    and a tree's only branch are kept. Returns (parents, pos) re-indexed, parents first."""
    parents = np.asarray(parents, np.int64)
    n = len(parents)
    kids = np.bincount(parents[parents >= 0], minlength=n)
    seg = np.zeros(n)
    seg[1:] = np.linalg.norm(pos[1:] - pos[parents[1:]], axis=1)
    drop = np.zeros(n, bool)
    for tip in np.flatnonzero(kids == 0):
        chain, length, v = [], 0.0, int(tip)
        while v > 0 and kids[v] <= 1:
            chain.append(v)
            length += seg[v]
            v = int(parents[v])
        if v >= 0 and kids[v] >= 2 and length < min_len:
            drop[chain] = True
    keep, newp, _ = without_nodes(parents, drop)
    return newp, pos[keep]
