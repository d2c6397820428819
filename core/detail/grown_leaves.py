"""Leaf clusters of generated trees (no video; paper §5 "the species' own foliage") and how full
a crown is: :func:`envelope_cover`, the share of the envelope's front view that the leaf blades
cover, which a species keeps from its source (``leaves["fill"]``) and :func:`grow_leaves` tops
its clusters up to (issue 19: generated crowns as full as the source's).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..envelope import Envelope
from ..topology import trunk_chain
from .leaf_clusters import BARK_RADIUS_SHARE, LeafParams, leaves_for_form, make_clusters
from .leaf_cover import card_footprint, uncovered_sites

#: rows of the raster the envelope's front view is measured on (a cluster is ~10 px across)
COVER_RASTER_PX = 256

#: top-up rounds (each adds clusters into the biggest holes, then measures again)
FILL_ROUNDS = 4
#: a cluster added into a hole hangs within this many cluster radii of a thin branch (seen from
#: the front): no foliage floating in the air
REACH: float = 2.0
#: ... and within this many of the thin branch that carries it (twigs are not drawn)
CARRY: float = 3.0
#: ... and where they cannot reach, every cluster grows, at most by this factor
MAX_GROWTH: float = 1.5


def envelope_raster(env: Envelope, rows: int = COVER_RASTER_PX) -> tuple[np.ndarray, np.ndarray, float]:
    """The envelope's front view on a raster: ``(region (H, W) bool, base_px (2,), scale)`` where
    ``region`` is ``|x − centre(z)| ≤ radius(z)``, ``base_px`` the origin (trunk base) in px and
    ``scale`` metres per px (the envelope's height spans ``rows`` px; metres as stored)."""
    top = float(np.max(env.z))
    lo = min(float(np.min(env.z)), 0.0)
    scale = max(top - lo, 1e-9) / rows
    left = float(np.min(env.centre - env.radius))
    right = float(np.max(env.centre + env.radius))
    W = int(np.ceil((right - left) / scale)) + 5
    H = rows + 5
    base = np.array([2.0 - left / scale, 2.0 + top / scale])
    yy, xx = np.mgrid[0:H, 0:W]
    z = (base[1] - yy.ravel()) * scale
    c, r = env.at(z)
    region = (np.abs((xx.ravel() - base[0]) * scale - c) <= r).reshape(H, W)
    return region, base, scale


def envelope_cover(leaves, env: Envelope, rows: int = COVER_RASTER_PX) -> float:
    """Share (0..1) of ``env``'s front view (metres) that the blades of ``leaves``
    (:class:`..tree3d.LeafClusters` at rest, metres from the trunk base) cover, seen like the
    video (orthographic, front)."""
    region, base, scale = envelope_raster(env, rows)
    shape = (int(region.shape[0]), int(region.shape[1]))
    if leaves is None or leaves.count == 0 or not region.any():
        return 0.0
    fp = card_footprint(shape, leaves.pos, leaves.axis, leaves.scales(), leaves.radius,
                        leaves.leaf_size, leaves.cards, leaves.seed, base, scale, leaves.shape)
    return float((fp & region).sum() / region.sum())


def twig_anchors(tree, seed: int = 0) -> np.ndarray:
    """``(T, 3)`` rest positions (metres) of the twigs :func:`.twigs.add_twigs` would grow on
    ``tree`` (two generations copied from its own forks, as a reconstruction has them): where its
    fine branching reaches, which the generated skeleton's node budget leaves out."""
    from .twigs import TwigParams, add_twigs
    short = type(tree)(tree.parents, tree.nodes3d[:1], tree.radius, tree.level, tree.fps, tree.name, dict(tree.meta))
    tw = add_twigs(short, TwigParams(depth=2, seed=int(seed)))
    first = int(tw.meta.get("twigs", {}).get("first_node", tw.n_nodes)) if tw is not short else tw.n_nodes
    return np.asarray(tw.nodes3d[0][first:], np.float64).reshape(-1, 3)


def grow_leaves(tree, info: dict, density: float = 1.0, seed: int = 0, params: LeafParams | None = None,
                envelope: Envelope | None = None):
    """Leaf clusters for a generated tree (no video): around its thin-branch nodes (radius below
    ``BARK_RADIUS_SHARE`` of the trunk's), ``info["per_node"] × density`` clusters per node, each
    ``info["radius_frac"] / √density`` of the height (the species' own foliage, paper §5: fewer,
    larger clusters), in the species' leaf colour ±8 %, axis away from the crown centre, flutter
    as for a reconstruction. When ``info`` has the source's ``"fill"`` and ``envelope`` (metres) is
    given, clusters are added into the envelope's largest uncovered holes (each on its nearest
    thin node, at that node's depth) until the blades cover that share of the envelope's front
    view, as the source's covered its own. ``info`` is :func:`..generate.species.leaf_info` of
    the source. Returns :class:`LeafClusters` or None."""
    p = params or LeafParams()
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x1EAF])
    rest = tree.nodes3d[0].astype(np.float64)
    r = np.asarray(tree.radius, np.float64)
    thin = np.flatnonzero((r < BARK_RADIUS_SHARE * r.max()) & (np.arange(tree.n_nodes) > 0))
    if tree.meta.get("form") == "palm":                     # a palm's leaflets: along its fronds
        chain = np.zeros(tree.n_nodes, bool)
        chain[trunk_chain(tree.parents)] = True
        thin = np.flatnonzero(~chain)
    if len(thin) == 0 or density <= 0:
        return None
    H = max(float(np.ptp(rest[:, 2])), 1e-6)
    # the source's clusters per thin branch node were counted without its twigs (species.leaf_info
    # of detail.twigs.without_twigs), so the count is too; they hang on the twigs as well
    first = int((tree.meta.get("twigs") or {}).get("first_node", tree.n_nodes))
    n_thin = int(np.sum(thin < first)) or len(thin)
    n = int(min(p.max_clusters, max(1, round(info["per_node"] * density * n_thin))))
    node = rng.choice(thin, n, replace=n > len(thin))
    radius = float(info["radius_frac"]) * H / np.sqrt(min(max(density, 1e-3), 1.0))
    pos = rest[node] + rng.normal(scale=0.35 * radius, size=(n, 3))
    target = info.get("fill")
    size = 1.0
    if target is not None and envelope is not None:
        drawn = first < tree.n_nodes                        # the tree carries its twigs
        anchors = rest[thin] if drawn else np.vstack([rest[thin], twig_anchors(tree, seed)])
        node, pos, size = _top_up(node, pos, rest, thin, anchors, radius, float(target), envelope,
                                  int(info["cards"]), seed, p.max_clusters, rng)
    colour = np.clip(np.asarray(info["colour"], np.float64)[None] * rng.uniform(0.92, 1.08, (len(node), 1)), 0, 1)
    dark = (pos[:, 1] - pos.mean(0)[1]) > 0                 # behind the crown centre
    leaves = make_clusters(tree, node, pos, colour, dark, radius, info["cards"], seed,
                           None if size == 1.0 else np.full(len(node), size, np.float32), p)
    return leaves_for_form(tree, leaves, tree.meta.get("form"))


def _top_up(node: np.ndarray, pos: np.ndarray, rest: np.ndarray, thin: np.ndarray, anchors: np.ndarray,
            radius: float, target: float, env: Envelope, cards: int, seed: int, cap: int,
            rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float]:
    """``node (S,)`` / ``pos (S, 3)`` changed so the clusters' blades cover ``target`` of ``env``'s
    front view: when they cover more, the fewest of them (in their random order) that still
    cover it — found by bisection, cover grows with every cluster; when less, clusters added
    (at most ``cap`` in all), each round one at the deepest point of each of the largest holes,
    as many as the missing area needs at one cluster's own footprint, where one of ``anchors
    (A, 3)`` (the thin branches and the twigs the tree would grow, :func:`twig_anchors`) is within
    :data:`REACH` cluster radii, at its depth, carried by the nearest thin branch (at most
    :data:`CARRY` radii away); if the crown's branches leave holes no cluster reaches, every
    cluster then grows (bisection, up to :data:`MAX_GROWTH` × its size) until the cover is reached.
    Returns the clusters and their size factor."""
    from .leaf_clusters import cluster_axes
    region, base, scale = envelope_raster(env)
    shape = (int(region.shape[0]), int(region.shape[1]))
    area = float(region.sum())
    if area == 0:
        return node, pos, 1.0
    leaf_size = 0.55 * radius

    def cover(q: np.ndarray, size: float = 1.0) -> tuple[float, np.ndarray]:
        fp = card_footprint(shape, q, cluster_axes(q), np.full(len(q), size), radius, leaf_size, cards, seed,
                            base, scale)
        return float((fp & region).sum()) / area, fp

    share, covered = cover(pos)
    if share > target:
        lo, hi = 1, len(pos)                      # cover(pos[:hi]) ≥ target
        while lo < hi:
            mid = (lo + hi) // 2
            if cover(pos[:mid])[0] >= target:
                hi = mid
            else:
                lo = mid + 1
        return node[:hi], pos[:hi], 1.0
    one = card_footprint(shape, np.array([[0.0, 0.0, 0.5 * float(env.z.max())]]), np.array([[0.0, 0.0, 1.0]]),
                         np.ones(1), radius, leaf_size, cards, seed, base, scale)
    per_cluster = max(float(one.sum()), 1.0)
    near = cKDTree(rest[thin][:, [0, 2]])
    reach = cKDTree(anchors[:, [0, 2]])
    for _ in range(FILL_ROUNDS):
        room = cap - len(pos)
        if share >= target or room <= 0:
            break
        sites = uncovered_sites(region, covered, radius / scale, deepest_first=True)
        if len(sites) == 0:
            break
        need = int(np.ceil((target - share) * area / per_cluster))
        xz = np.stack([(sites[:, 0] - base[0]) * scale, (base[1] - sites[:, 1]) * scale], 1)
        d, a = reach.query(xz)
        dn, k = near.query(xz)                      # carried by the nearest thin branch's bone
        # holes no branch or twig reaches stay open, and none far from a drawn branch
        ok = (d <= REACH * radius) & (dn <= CARRY * radius)
        xz, a, k = xz[ok][: min(need, room)], a[ok][: min(need, room)], k[ok][: min(need, room)]
        if len(a) == 0:
            break
        y = anchors[a, 1] + rng.normal(scale=0.35 * radius, size=len(a))
        node = np.concatenate([node, thin[k]])
        pos = np.concatenate([pos, np.stack([xz[:, 0], y, xz[:, 1]], 1)])
        share, covered = cover(pos)
    if share >= target:
        return node, pos, 1.0
    lo_f, hi_f = 1.0, float(MAX_GROWTH)
    if cover(pos, hi_f)[0] < target:
        return node, pos, hi_f
    for _ in range(8):
        f_mid = 0.5 * (lo_f + hi_f)
        if cover(pos, f_mid)[0] >= target:
            hi_f = f_mid
        else:
            lo_f = f_mid
    return node, pos, hi_f
