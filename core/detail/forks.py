"""Forks that join (issue 36 part 3, seed 001's bifurcations): where the branch tubes of
:func:`core.detail.branch_mesh.tube_arrays` meet, one closed surface instead of tubes that
interpenetrate.

At every node the tubes that meet there end in a ring short of the node: the incoming bone's last
ring ``A`` at ``a`` metres before it, each child's first ring ``C_i`` at ``t_i`` metres after it.

* A node with one child (a branch going on) is bridged ring to ring by ``S`` quads, the child's
  ring turned by the cyclic shift that pairs the nearest vertices (no twist). ``a = t = r·max(tan
  (β/2), 0.3)``, ``β`` the bend: the two rings never cross on the bend's inner side.
* A fork (two or more children, or a root with several) is the **convex hull** of its rings with
  the rings' own faces taken out (B-Mesh, Ji et al. 2010): every ring must be a face of the hull, so
  the rings start at ``r`` (the node's radius) and the rings that are not yet on the hull move out
  along their bones by ×1.4 a round (at most 0.45 of a bone's length, or 0.9 less what its other
  end takes when that end is a bend or a tip). When they cannot all be placed (a fork narrower
  than its branches' thickness allows), the thinnest child that does not fit keeps a tube starting
  inside the fork (counted in ``overlapping``) and the others join without it.

The hull is taken over the rings' ideal circles (no bark) and its faces oriented by its outward
plane normals, so the joined surface is closed and faces out; the bark's relief then moves the
same vertices. Every vertex keeps its bone (weight 1): a junction's faces span the incoming bone's
ring and the children's, so when a child turns about the fork the junction stretches between the
two bones' rings as a blended weight would move it.

**Pipe model at the junction**: the continuing child (the thickest) starts at
``r_main = (r_n^Δ − Σ_side r_i^Δ)^(1/Δ)`` (the node's radius ``r_n``; the tree's pipe exponent Δ,
Leonardo's 2 by default), kept between its own tail radius and ``r_n``: the cross-sections leaving
a fork add up to the one entering it.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from .. import bones

#: a fork's rings start this many node radii from the node
START = 1.0
#: a ring not on the hull moves out by this factor a round
GROW = 1.4
#: a junction ring lies this share of its bone's length from the node at most when the bone's
#: other end is a fork too (else up to 0.9 of the bone less what its other end takes)
REACH = 0.45
#: a bend's rings sit at least this many node radii from the node
BEND_MIN = 0.3

#: ``ring_points(bone (M,), tau (M,), radius (M,)) -> (M, S, 3)``: ideal ring vertices
RingFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


@dataclass
class ForkPlan:
    """Where each bone's rings run and how they join. ``tau_start``, ``tau_end (B,)`` the first and
    last ring's position along the bone (0 head, 1 tail; < 0 inside the parent when overlapping);
    ``r_head (B,)`` metres, the head radii after the pipe model; ``head_cap``, ``tail_cap (B,)``
    bool: the tube keeps that end's cap; ``tris`` the junctions' triangles as ``(bone·2 + end,
    k)`` corners resolved by :meth:`polygons`, ``tri_nodes`` their fork nodes; ``quads`` the bends'
    quads likewise; ``forks`` nodes with two or more tubes leaving,
    ``fork_children`` the tubes leaving them, ``joined_children`` of those joined, ``bends`` nodes
    bridged by a band."""

    tau_start: np.ndarray
    tau_end: np.ndarray
    r_head: np.ndarray
    head_cap: np.ndarray
    tail_cap: np.ndarray
    tris: list[np.ndarray] = field(default_factory=list)     # each (T, 3, 2): (bone·2 + end, k)
    tri_nodes: list[np.ndarray] = field(default_factory=list)  # each (T,): the fork node
    quads: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 2), np.int64))
    forks: int = 0
    fork_children: int = 0
    joined_children: int = 0
    bends: int = 0

    @property
    def overlapping(self) -> int:
        """Tubes leaving a fork that still start inside it (their fork could not place their ring)."""
        return self.fork_children - self.joined_children

    def polygons(self, K: int, S: int) -> tuple[np.ndarray, np.ndarray]:
        """The junctions' triangles ``(T, 3)`` and bands' quads ``(Q, 4)`` as vertex indices of
        :func:`tube_arrays`'s layout (ring ``j`` of bone ``b``: ``(b·K + j)·S + k``; end 0 = the
        first ring, 1 = the last)."""
        def index(x):
            bone, end = x[..., 0] // 2, x[..., 0] % 2
            return (bone * K + end * (K - 1)) * S + x[..., 1]
        tris = np.concatenate(self.tris) if self.tris else np.zeros((0, 3, 2), np.int64)
        return index(tris), index(self.quads)


def _node_tables(parents: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """``edges (B, 2)``, ``in_bone (N,)`` (the bone ending at each node, −1 at the root) and the
    bones leaving each node."""
    edges = bones.bone_edges(parents)
    N = len(parents)
    in_bone = np.full(N, -1)
    in_bone[edges[:, 1]] = np.arange(len(edges))
    order = np.argsort(edges[:, 0], kind="stable")
    split = np.searchsorted(edges[order, 0], np.arange(N + 1))
    out = [order[split[n]:split[n + 1]] for n in range(N)]
    return edges, in_bone, out


def pipe_heads(parents: np.ndarray, r_head: np.ndarray, r_tail: np.ndarray, delta: float = 2.0) -> np.ndarray:
    """``r_head (B,)`` with each fork's continuing child (its thickest) started at the pipe model's
    ``(r_n^Δ − Σ_side r_i^Δ)^(1/Δ)``, kept within ``[r_tail, r_n]`` (``r_n`` the incoming bone's
    tail radius; forks at the root keep theirs)."""
    edges, in_bone, out = _node_tables(parents)
    r = np.asarray(r_head, np.float64).copy()
    forks = [n for n in range(len(parents)) if len(out[n]) >= 2 and in_bone[n] >= 0]
    for n in forks:
        kids = out[n]
        main = kids[np.argmax(r_tail[kids])]
        rn = float(r_tail[in_bone[n]])
        side = float(np.sum(r_head[kids[kids != main]] ** delta))
        want = max(rn ** delta - side, 0.0) ** (1.0 / delta)
        r[main] = float(np.clip(want, r_tail[main], rn))
    return r


def _ring_ok(simplices: np.ndarray, hull_verts: np.ndarray, ring: np.ndarray, S: int) -> np.ndarray:
    """``(R,)`` bool: ring ``i`` (local vertices ``i·S … i·S + S − 1``) is a face of the hull: all its
    vertices are hull vertices and S − 2 hull triangles lie wholly in it."""
    R = int(ring.max()) + 1
    on = np.zeros(R * S, bool)
    on[hull_verts] = True
    all_on = on.reshape(R, S).all(axis=1)
    r = ring[simplices]
    own = (r[:, 0] == r[:, 1]) & (r[:, 1] == r[:, 2])
    count = np.bincount(r[own, 0], minlength=R)
    return all_on & (count == S - 2)


def plan_forks(parents: np.ndarray, length: np.ndarray, r_head: np.ndarray, r_tail: np.ndarray,
               ext: np.ndarray, ring_points: RingFn, tangents: Callable[[np.ndarray, np.ndarray], np.ndarray],
               S: int, delta: float = 2.0) -> ForkPlan:
    """Place every node's junction rings and build the junctions (module docstring).

    ``length (B,)`` metres the bones' lengths, radii ``(B,)`` metres (head radii before the pipe
    model), ``ext (B,)`` metres the overlapping extension a child's tube starts with when its fork
    cannot join; ``ring_points`` gives ideal ring vertices and ``tangents(bone, tau) -> (M, 3)`` the
    centre line's unit tangent."""
    edges, in_bone, out = _node_tables(parents)
    B = len(edges)
    r_head = pipe_heads(parents, r_head, r_tail, delta)
    L = np.maximum(length, 1e-12)
    tau_start = np.where(in_bone[edges[:, 0]] >= 0, -ext / L, 0.0)
    tau_end = np.ones(B)
    head_cap = np.ones(B, bool)
    tail_cap = np.ones(B, bool)
    plan = ForkPlan(tau_start, tau_end, r_head, head_cap, tail_cap)
    if B == 0:
        return plan
    n_out = np.array([len(o) for o in out])
    r_node = np.where(in_bone >= 0, r_tail[np.maximum(in_bone, 0)], 0.0)
    np.maximum.at(r_node, edges[:, 0], r_head)
    lim = REACH * length

    # bends: one child going on, bridged by a band
    bend = np.flatnonzero((n_out == 1) & (in_bone >= 0))
    if len(bend):
        p = in_bone[bend]
        c = np.array([out[n][0] for n in bend])
        tp = tangents(p, np.ones(len(p)))
        tc = tangents(c, np.zeros(len(c)))
        beta = np.arccos(np.clip(np.sum(tp * tc, axis=1), -1.0, 1.0))
        d = r_node[bend] * np.maximum(np.tan(np.minimum(beta, 2.6) / 2), BEND_MIN)
        d = np.minimum(d, np.minimum(lim[p], lim[c]))
        plan.tau_end[p] = 1.0 - d / L[p]
        plan.tau_start[c] = d / L[c]
        ra = ring_points(p, plan.tau_end[p], _radius_at(r_head, r_tail, p, plan.tau_end[p]))
        rc = ring_points(c, plan.tau_start[c], _radius_at(r_head, r_tail, c, plan.tau_start[c]))
        k = np.arange(S)
        shift = (k[:, None] + k[None]) % S                                    # (shift, k)
        cost = np.sum((ra[:, None] - rc[:, shift]) ** 2, axis=(-1, -2))       # (M, S)
        s = np.argmin(cost, axis=1)[:, None]
        M = len(p)
        keys = np.broadcast_to(np.stack([2 * p + 1, 2 * c, 2 * c, 2 * p + 1], axis=-1)[:, None], (M, S, 4))
        kn = (k + 1) % S
        ks = np.stack([np.broadcast_to(k, (M, S)), (k + s) % S, (kn + s) % S, np.broadcast_to(kn, (M, S))], axis=-1)
        quads = np.stack([keys, ks], axis=-1)
        plan.quads = quads.reshape(-1, 4, 2)
        plan.head_cap[c] = False
        plan.tail_cap[p] = False
        plan.bends = len(bend)

    # forks: the convex hull of the rings meeting there
    fork_nodes = np.flatnonzero(n_out >= 2)
    plan.forks = len(fork_nodes)
    plan.fork_children = int(n_out[fork_nodes].sum())
    if not len(fork_nodes):
        return plan
    # each fork's rings: (bone, end) with end 1 = the incoming bone's tail, 0 = a child's head
    members = [np.array(([[in_bone[n], 1]] if in_bone[n] >= 0 else []) + [[b, 0] for b in out[n]], np.int64)
               for n in fork_nodes]
    tip = np.zeros(B, bool)
    tip[np.flatnonzero(n_out[edges[:, 1]] == 0)] = True
    lone_root = (in_bone[edges[:, 0]] < 0) & (n_out[edges[:, 0]] == 1)
    # first every fork within REACH of its bones; then the forks that did not fit again, each ring
    # reaching as far as the bone's other end, now placed, leaves free
    deferred = list(range(len(fork_nodes)))
    for second in (False, True):
        used_tail = np.where(tip, 0.0, np.where(plan.tail_cap, REACH, 1.0 - plan.tau_end) * length)
        used_head = np.where(lone_root, 0.0, np.where(plan.head_cap, REACH, plan.tau_start) * length)
        reach_head = np.maximum(REACH * length, 0.9 * length - used_tail)    # a child's first ring
        reach_tail = np.maximum(REACH * length, 0.9 * length - used_head)    # the incoming bone's last ring
        limits = {f: np.where(members[f][:, 1] == 1, reach_tail[members[f][:, 0]], reach_head[members[f][:, 0]])
                  for f in deferred}
        dist = {f: np.minimum(START * r_node[fork_nodes[f]], limits[f]) for f in deferred}
        deferred = _place(plan, deferred, fork_nodes, members, limits, dist, L, r_head, r_tail, ring_points, S,
                          second)
    return plan


def _place(plan: ForkPlan, pending: list[int], nodes: np.ndarray, members: list[np.ndarray], limits: dict, dist: dict,
           L: np.ndarray, r_head: np.ndarray, r_tail: np.ndarray, ring_points: RingFn, S: int,
           drop: bool) -> list[int]:
    """Move the rings of forks ``pending`` out until each fork's rings are all faces of their hull
    and record it (:func:`_join`); returns the forks that reached their ``limits`` (with ``drop``:
    the thinnest child that does not fit is left out instead, keeping its overlapping tube, and the
    rest tried again; nothing is returned)."""
    deferred = []
    while pending:
        rows = np.concatenate([members[f] for f in pending])
        d = np.concatenate([dist[f] for f in pending])
        tau = np.where(rows[:, 1] == 1, 1.0 - d / L[rows[:, 0]], d / L[rows[:, 0]])
        pts = ring_points(rows[:, 0], tau, _radius_at(r_head, r_tail, rows[:, 0], tau))   # (M, S, 3)
        start = np.concatenate([[0], np.cumsum([len(members[f]) for f in pending])])
        still = []
        for i, f in enumerate(pending):
            m, lim = members[f], limits[f]
            ok = _hull_rings(pts[start[i]:start[i + 1]], S)
            if isinstance(ok, ConvexHull):
                _join(plan, int(nodes[f]), m, d[start[i]:start[i + 1]], L, ok, S)
                continue
            grow = np.where(ok, dist[f], dist[f] * GROW)
            if np.all(grow[~ok] > lim[~ok] + 1e-12):
                if not drop:
                    deferred.append(f)
                    continue
                kids = np.flatnonzero(m[:, 1] == 0)
                if len(m) - 1 < 2 or len(kids) < 2:
                    continue
                bad = kids[~ok[kids]] if (~ok[kids]).any() else kids
                out = bad[np.argmin(r_tail[m[bad, 0]])]
                keep = np.arange(len(m)) != out
                members[f], limits[f], dist[f] = m[keep], lim[keep], dist[f][keep]
            else:
                dist[f] = np.minimum(grow, lim)
            still.append(f)
        pending = still
    return deferred


def _hull_rings(pts: np.ndarray, S: int) -> np.ndarray | ConvexHull:
    """The convex hull of rings ``pts (R, S, 3)`` when every ring is one of its faces, else ``(R,)``
    bool: which rings are."""
    R = len(pts)
    ring = np.repeat(np.arange(R), S)
    try:
        hull = ConvexHull(pts.reshape(-1, 3), qhull_options="QJ")
    except QhullError:
        return np.zeros(R, bool)
    ok = _ring_ok(hull.simplices, hull.vertices, ring, S)
    return hull if ok.all() else ok


def _radius_at(r_head: np.ndarray, r_tail: np.ndarray, bone: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """The tube's radius before bark at ``tau`` along ``bone`` (linear taper, ``tau`` clipped to
    [0, 1])."""
    w = np.clip(tau, 0.0, 1.0)
    return r_head[bone] * (1.0 - w) + r_tail[bone] * w


def _join(plan: ForkPlan, node: int, m: np.ndarray, d: np.ndarray, L: np.ndarray, hull: ConvexHull, S: int) -> None:
    """Record a joined fork: its rings' positions and the hull's faces that are not a ring's own,
    turned to face out."""
    b, end = m[:, 0], m[:, 1]
    tail = end == 1
    plan.tau_end[b[tail]] = 1.0 - d[tail] / L[b[tail]]
    plan.tail_cap[b[tail]] = False
    plan.tau_start[b[~tail]] = d[~tail] / L[b[~tail]]
    plan.head_cap[b[~tail]] = False
    simp = hull.simplices
    r = simp // S
    keep = ~((r[:, 0] == r[:, 1]) & (r[:, 1] == r[:, 2]))
    simp = simp[keep]
    P = hull.points
    n = np.cross(P[simp[:, 1]] - P[simp[:, 0]], P[simp[:, 2]] - P[simp[:, 0]])
    flip = np.sum(n * hull.equations[keep, :3], axis=1) < 0
    simp[flip] = simp[flip][:, ::-1]
    key = 2 * b + end
    plan.tris.append(np.stack([key[simp // S], simp % S], axis=-1))
    plan.tri_nodes.append(np.full(len(simp), node))
    plan.joined_children += int((~tail).sum())

