"""The default ``traced`` 2D skeleton: branches traced in the image, the hierarchy as the crown's map.

1. Bark evidence ``E = dark · steady``: the share of frames a pixel is dark times
   ``exp(-std / s)`` (foliage flickers, bark does not), from :class:`AppearanceMaps`.
2. Ridges: multi-scale Hessian ridge filter of E (``σ² · max(0, −λ_min)``, max over scales),
   joined (max) with the ridges of frame 1's bark-coloured pixels (:mod:`.frame_evidence`): a
   thin limb that sways by more than its width leaves no ridge in E, but is sharp in frame 1.
   A trunk wider than those ridges that E misses (sunlit: brighter than its crown) is found by
   its colour at the outline's stem and gets a ridge at its own scale (:func:`with_frame1`).
3. A cost per pixel, low on ridges, higher in foliage, highest on bright, steady, smooth
   pixels (sky seen through the crown) and on what frame 1 shows as background; pixels outside
   the outline are not in the graph.
4. Shortest paths (Dijkstra, 8-connected) from the trunk base to targets: the clusters of the
   normalized-cut hierarchy (centroids, and the points where two sibling clusters meet), twig
   ends below its finest level (each leaf cluster split by k-means) and the far ends of traced
   ridge fragments. The union of the paths is a tree; a path that comes within a merge radius of
   the tree (wider across thick bark) joins it, so a wide trunk gives one chain, not parallel lines.
5. The pixel tree is cut into chains between the root, branch points and tips, resampled every
   ``spacing`` px, short spurs pruned, and made binary.

When the crown hangs to the ground in front of its trunk (:func:`hidden_trunk`: frame 1's tree is
wide at its base), the trunk cannot be traced: it rises from the tree's lowest point, walled off
so every path climbs it to its top, and foliage beside it below the top is no branch end.

When no bark evidence exists (a dense, front-lit crown), the skeleton is built from the
hierarchy alone (:func:`hierarchy_geometry`: a straight trunk, clusters where their children
meet, twigs grown as a spanning tree), so a valid skeleton always comes out, with a warning.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.sparse.csgraph import dijkstra

from ..outline import Outline
from ..progress import ProgressFn, report
from ..topology import branching_level
from .appearance import AppearanceMaps
from .frame_evidence import FrameEvidence, frame_evidence
from .hierarchy import Hierarchy
from .node_motion import follow_tracks
from .pixel_graph import grid_graph
from .skeleton2d import (
    NODE_MOTION_SCALE,
    Skeleton2D,
    binarize,
    crown_scale,
)
from .stems import hidden_trunk, leader_curve, leader_tip, straighten_stem
from .tracks import Tracks


@dataclass
class TraceParams:
    """Settings of the traced skeleton (fractions are of the tree's size)."""

    ridge_scales: tuple = (1.0, 2.0, 3.5, 6.0)   # working px
    foliage_cost: float = 6.0        # extra cost per px away from ridges
    sky_cost: float = 30.0           # extra cost per px of bright steady sky
    min_fragment: float = 0.05       # ridge fragments shorter than this are ignored
    spacing: float = 0.035           # chain node spacing
    min_spur: float = 0.03           # side paths shorter than this are pruned (unless a cluster)
    merge_radius: float = 0.015      # paths this close to the tree join it instead of running beside
    twig_tracks: int = 6             # tracks per twig target below the finest hierarchy level
    max_twigs: int = 300             # at most this many twig targets (many tracks in a large video)
    frame1: bool = True              # also trace on frame 1's own pixels (see frame_evidence)
    frame_ridge_scales: tuple = (1.0, 2.0)   # working px: bark in one frame is sharp and thin
    trunk_ridge_scale: float = 0.29  # × the stem's measured width: the ridge scale centred on a wide trunk
    background_cost: float = 6.0     # extra cost per px of what frame 1 shows as background
    bark_colour_tol: float = 2.0     # CIELAB distance beyond the trunk's own colour spread
    max_bark_share: float = 0.3      # a crown more bark-coloured than this: colour tells nothing
    base_width: float = 0.3          # outline this share of its widest row wide at 5 % of its height: hidden trunk
    hidden_trunk: float = 0.3        # a hidden trunk rises to this share of the height (a broadleaf's first fork)


def relative_decay(x: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """``exp(−x / median(x inside the outline))``: 1 where x is small for this tree, → 0 where large."""
    scale = float(np.median(x[inside])) if inside.any() else 1.0
    return np.exp(-x / max(scale, 1e-3))


def bark_evidence(maps: AppearanceMaps) -> np.ndarray:
    """``E (h, w)`` in [0, 1]: dark in most frames × steady over time, zero outside the outline."""
    inside = maps.mask
    e = maps.dark * relative_decay(maps.std, inside)
    e[~inside] = 0.0
    return e.astype(np.float32)


def ridge_filter(img: np.ndarray, scales) -> np.ndarray:
    """Multi-scale bright-ridge strength ``σ² · max(0, −λ_min(H))``, max over ``scales`` (px)."""
    out = np.zeros_like(img, dtype=np.float32)
    for s in scales:
        g = cv2.GaussianBlur(img, (0, 0), s)
        dxx = cv2.Sobel(g, cv2.CV_32F, 2, 0, ksize=3)
        dyy = cv2.Sobel(g, cv2.CV_32F, 0, 2, ksize=3)
        dxy = cv2.Sobel(g, cv2.CV_32F, 1, 1, ksize=3)
        tr, det_part = dxx + dyy, np.sqrt((dxx - dyy) ** 2 + 4 * dxy ** 2)
        lam_min = 0.5 * (tr - det_part)
        out = np.maximum(out, (s * s) * np.maximum(-lam_min, 0.0))
    return out


def normalized(ridge: np.ndarray, inside: np.ndarray) -> tuple[np.ndarray, float]:
    """``(clip(ridge / s, 0, 1), s)`` with ``s`` the 99th percentile of ``ridge (h, w)`` inside
    ``inside (h, w)``; all zeros when there is no ridge there (s ≤ 1e-6)."""
    r = ridge[inside]
    s = float(np.percentile(r, 99)) if r.size else 0.0
    return (np.clip(ridge / s, 0, 1) if s > 1e-6 else np.zeros_like(ridge)), s


def sky_likeness(maps: AppearanceMaps) -> np.ndarray:
    """``(h, w)`` in [0, 1]: bright relative to the tree, steady over time and smooth in space."""
    inside = maps.mask
    if not inside.any():
        return np.zeros_like(maps.mean)
    lo, hi = np.percentile(maps.mean[inside], [50, 97])
    bright = np.clip((maps.mean - lo) / max(hi - lo, 1.0), 0, 1)
    steady = relative_decay(maps.std, inside)
    first = cv2.GaussianBlur(maps.first.mean(-1).astype(np.float32), (0, 0), 1.5)
    grad = cv2.GaussianBlur(np.hypot(cv2.Sobel(first, cv2.CV_32F, 1, 0), cv2.Sobel(first, cv2.CV_32F, 0, 1)),
                            (0, 0), 2.0)
    smooth = relative_decay(grad, inside)
    return cv2.GaussianBlur((bright * steady * smooth).astype(np.float32), (0, 0), 1.0)


def ridge_targets(ridge_mask: np.ndarray, root: int, dist: np.ndarray, min_len: float) -> list[int]:
    """For every thinned ridge fragment of at least ``min_len`` px, its pixel farthest from the root."""
    thin = cv2.ximgproc.thinning(ridge_mask.astype(np.uint8) * 255) > 0
    n, lab = cv2.connectedComponents(thin.astype(np.uint8), connectivity=8)
    flat_lab = lab.ravel()
    out = []
    for c in range(1, n):
        pix = np.flatnonzero(flat_lab == c)
        if len(pix) < min_len:
            continue
        d = dist[pix]
        if not np.isfinite(d).any():
            continue
        out.append(int(pix[np.nanargmax(np.where(np.isfinite(d), d, -1))]))
    return out


def path_tree(pred: np.ndarray, dist: np.ndarray, cost: np.ndarray, root: int, targets: list[int],
              width: int, radius: np.ndarray) -> dict[int, int]:
    """Union of shortest paths from each target back to ``root``: {pixel: parent pixel}.

    Targets are added farthest first. Walking back from a target, the path joins the tree as soon
    as it passes within ``radius`` px (the tree pixel's, flat: wider on thick branches) of a tree pixel
    that is not much farther from the root (by less than crossing that radius would cost), so
    paths that would run side by side (a wide trunk has many near-equal shortest paths) share one
    line. ``cost`` is per pixel (flat).
    """
    height = len(pred) // width
    on_tree = np.zeros((height, width), bool)
    on_tree.flat[root] = True
    parent: dict[int, int] = {}
    R = int(radius.max()) if len(radius) else 0
    for t in sorted(targets, key=lambda u: -dist[u]):
        u = t
        path = [u]
        join = None
        while u != root:
            y, x = divmod(u, width)
            if on_tree[y, x]:
                join = u
                break
            y0, y1, x0, x1 = max(y - R, 0), min(y + R + 1, height), max(x - R, 0), min(x + R + 1, width)
            wy, wx = np.nonzero(on_tree[y0:y1, x0:x1])
            if len(wy):
                cand = (wy + y0) * width + (wx + x0)
                d2 = (wy + y0 - y) ** 2 + (wx + x0 - x) ** 2
                ok = (d2 <= radius[cand] ** 2) & (dist[cand] <= dist[u] + 2 * radius[cand] * cost[u])
                if ok.any():
                    join = int(cand[ok][np.argmin(d2[ok])])
                    path.append(join)
                    break
            p = int(pred[u])
            if p < 0:
                break
            u = p
            path.append(u)
        if join is None and u != root:
            continue   # unreachable target
        for a, b in zip(path[:-1], path[1:]):
            parent[a] = b
            on_tree.flat[a] = True
    return parent


def simplify_tree(parent: dict[int, int], root: int, keep: set[int], width: int,
                  spacing: float, min_spur: float) -> tuple[np.ndarray, np.ndarray]:
    """Pixel tree → node tree: root, branch points, tips and chain nodes every ``spacing`` px.

    Side branches shorter than ``min_spur`` px are dropped, or half that when they lead to a
    ``keep`` pixel (a leaf cluster: its twig is real even when short).
    Returns ``parents (N,)`` and ``pos (N, 2)`` (x, y) working px; node 0 is the root.
    """
    kids: dict[int, list[int]] = {}
    for c, p in parent.items():
        kids.setdefault(p, []).append(c)

    def xy(u):
        return np.array([u % width, u // width], float)

    # lengths of the subtree below each pixel, to prune short spurs (iterative post-order)
    order = [root]
    i = 0
    while i < len(order):
        order.extend(kids.get(order[i], []))
        i += 1
    reach: dict = {}
    has_keep: dict = {}
    for u in reversed(order):
        ch = kids.get(u, [])
        reach[u] = max((reach[c] + np.linalg.norm(xy(c) - xy(u)) for c in ch), default=0.0)
        has_keep[u] = (u in keep) or any(has_keep[c] for c in ch)

    parents, pos = [-1], [xy(root)]
    stack = [(root, 0, 0.0)]   # (pixel, node index of last emitted ancestor, arc length since it)
    while stack:
        u, last, run = stack.pop()
        ch = [c for c in kids.get(u, []) if reach[c] >= (0.5 if has_keep[c] else 1.0) * min_spur]
        for c in ch:
            step = float(np.linalg.norm(xy(c) - xy(u)))
            r = run + step
            n_kids = len([g for g in kids.get(c, []) if reach[g] >= (0.5 if has_keep[g] else 1.0) * min_spur])
            if n_kids != 1 or r >= spacing:
                parents.append(last)
                pos.append(xy(c))
                stack.append((c, len(pos) - 1, 0.0))
            else:
                stack.append((c, last, r))
    return np.array(parents, np.int32), np.array(pos)


def meeting_points(hier: Hierarchy, p0: np.ndarray, knn: int = 8) -> dict[int, np.ndarray]:
    """Where the two child clusters of every internal cluster meet: the mean of the midpoints of
    kNN edges joining one child's tracks to the other's (px, ``p0 (P, 2)`` frame-1 positions)."""
    from scipy.spatial import cKDTree
    out: dict = {}
    ch: dict = {}
    for c, p in enumerate(hier.parent):
        if p >= 0:
            ch.setdefault(int(p), []).append(c)
    for c, kids in ch.items():
        if len(kids) != 2:
            continue
        a, b = hier.members[kids[0]], hier.members[kids[1]]
        if len(a) == 0 or len(b) == 0:
            continue
        k = min(knn, len(b))
        d, j = cKDTree(p0[b]).query(p0[a], k=k)
        d, j = d.reshape(len(a), k), j.reshape(len(a), k)
        # pairs closer than the typical neighbour spacing inside the cluster form the boundary
        all_idx = hier.members[c]
        kk = min(knn + 1, len(all_idx))
        sp = np.median(cKDTree(p0[all_idx]).query(p0[all_idx], k=kk)[0][:, -1])
        near = d <= 1.5 * sp
        if not near.any():
            i0, j0 = np.unravel_index(np.argmin(d), d.shape)
            near = np.zeros_like(d, bool)
            near[i0, j0] = True
        ia, kb = np.nonzero(near)
        mids = 0.5 * (p0[a][ia] + p0[b][j[ia, kb]])
        out[c] = mids.mean(0)
    return out


def foliage_targets(hier: Hierarchy, p0: np.ndarray, per_target: int) -> tuple[np.ndarray, np.ndarray]:
    """Twig ends below the finest hierarchy level: each leaf cluster's tracks split spatially
    (k-means, seeded) into groups of about ``per_target`` tracks.

    Returns their centroids ``(K, 2)`` px and the leaf cluster each belongs to ``(K,)``.
    """
    import warnings as _w

    from scipy.cluster.vq import kmeans2
    out, owner = [], []
    for c in hier.leaves:
        pts = p0[hier.members[c]].astype(np.float64)
        k = int(len(pts) // max(per_target, 1))
        if k < 2:
            continue
        with _w.catch_warnings():
            _w.simplefilter("ignore")          # "one of the clusters is empty": dropped below
            cent, lab = kmeans2(pts, k, minit="++", seed=np.random.default_rng(int(c)))
        used = cent[np.bincount(lab, minlength=k) > 0]
        out.extend(used)
        owner.extend([int(c)] * len(used))
    return np.array(out).reshape(-1, 2), np.array(owner, int)


def hierarchy_geometry(hier: Hierarchy, p0: np.ndarray, base: np.ndarray, size: float,
                       twigs: np.ndarray, owner: np.ndarray, spacing: float,
                       trunk_top: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Skeleton from the hierarchy alone (no bark seen): a straight trunk from ``base`` up to the
    lower crown (or to row ``trunk_top`` for a hidden trunk), then every cluster at the point
    where its two children meet (leaf clusters at their centroid, twig ends growing from their
    leaf cluster), joined by straight chains.

    ``p0 (P, 2)`` track positions, ``twigs (K, 2)`` with ``owner (K,)`` leaf cluster ids, all in
    the same px as ``base``; ``size`` tree height and ``spacing`` chain node spacing (px).
    Returns ``parents (N,)`` and ``pos (N, 2)``; node 0 is the base.
    """
    meet = meeting_points(hier, p0)
    place = np.array([meet[c] if c in meet else (p0[m].mean(0) if len(m) else base)
                      for c, m in enumerate(hier.members)], float)
    # trunk top: on the vertical through the base, at the lower crown (85% of tracks above it)
    y_top = min(max(place[0, 1], float(np.quantile(p0[hier.members[0], 1], 0.85))), base[1] - 0.15 * size)
    if trunk_top is not None:
        y_top = float(trunk_top)
    place[0] = [base[0], y_top]
    parents, pos = [-1], [np.asarray(base, float)]
    node_of: dict = {}

    def chain(a: int, b_xy: np.ndarray) -> int:
        """Append a straight chain from node ``a`` to ``b_xy``; return the last node's index."""
        n = max(1, int(np.ceil(np.linalg.norm(b_xy - pos[a]) / spacing)))
        start = pos[a]
        last = a
        for k in range(1, n + 1):
            parents.append(last)
            pos.append(start + (b_xy - start) * k / n)
            last = len(pos) - 1
        return last

    from ..topology import topological_order
    for c in topological_order(hier.parent):
        p = hier.parent[c]
        node_of[c] = chain(0 if p < 0 else node_of[p], place[c])
    # twig ends grow from their leaf cluster like a spanning tree: each (nearest first) hangs from
    # the closest node already placed for that cluster, so a big cluster is no star of twigs
    for c in np.unique(owner):
        mine = twigs[owner == c]
        anchors = [node_of[int(c)]]
        order = np.argsort(np.linalg.norm(mine - pos[anchors[0]], axis=1))
        for xy in mine[order]:
            near = min(anchors, key=lambda a: float(np.sum((pos[a] - xy) ** 2)))
            anchors.append(chain(near, np.asarray(xy, float)))
    return np.array(parents, np.int32), np.array(pos)


def trunk_base(ridge: np.ndarray, evidence: np.ndarray, mask: np.ndarray) -> tuple[int, int]:
    """(x, y) working px of the trunk base.

    The column of strongest ridge over the lowest quarter of the outline (a trunk runs through
    all of it, ground texture only through its last rows), followed downward from its strongest
    point while the ridge stays strong; without any ridge, the bottom-centre of the outline.
    """
    ys, xs = np.nonzero(mask)
    ybot, ytop = ys.max(), ys.min()
    band = max(3, int(0.25 * (ybot - ytop + 1)))
    rows = slice(max(ybot - band, 0), ybot + 1)
    col = (ridge[rows] * mask[rows]).sum(0)
    if col.max() <= 0:
        row = xs[ys == ybot]
        return int(round(row.mean())), int(ybot)
    x = int(np.argmax(np.convolve(col, np.ones(5) / 5, mode="same")))
    column = ridge[:, x] * mask[:, x]
    y0 = max(ybot - band, 0)
    y = y0 + int(np.argmax(np.convolve(column[y0:ybot + 1], np.ones(5) / 5, mode="same")))
    ref = float(column[y])
    while y + 1 <= ybot and mask[y + 1, x] and column[y + 1] >= 0.3 * ref:
        y += 1
    return x, int(y)


def with_frame1(params: TraceParams, maps: AppearanceMaps, rn: np.ndarray,
                size: float) -> tuple[np.ndarray, FrameEvidence | None, np.ndarray | None]:
    """The clip's normalized ridge strength ``rn (h, w)`` joined with frame 1's (see
    :mod:`.frame_evidence`): ``max(rn, ridge(bark₁) / p99)``, bark colour taken from the trunk
    (the lowest quarter of the outline where ``rn > 0.5``) or, when its colour does not tell the
    bark, from the outline's stem. A trunk wider than the frame's ridge scales whose middle the
    clip's ridge misses (median ``rn`` < 0.5 over the stem: sunlit, brighter than its crown) adds
    the scale ``trunk_ridge_scale`` × its width. Returns the joined ``rn``, frame 1's evidence
    (None when the outline leaves no background to compare with) and that trunk's ridge at its
    own scale alone (it marks the trunk's middle, where the finer scales mark its edges; None
    without such a trunk). ``size`` tree height (px)."""
    mask = maps.mask
    ys, _ = np.nonzero(mask)
    low = np.arange(mask.shape[0])[:, None] > ys.max() - 0.25 * size
    fe = frame_evidence(maps.first, mask, mask & low & (rn > 0.5), params.bark_colour_tol,
                        params.max_bark_share)
    trunk_ridge = None
    if fe is None:
        return rn, None, trunk_ridge
    if fe.bark is not None:
        scales = tuple(params.frame_ridge_scales)
        wide = params.trunk_ridge_scale * fe.trunk_width     # NaN without a stem
        rn_frame = normalized(ridge_filter(fe.bark, scales), mask)[0]
        # a trunk wider than the frame's scales that the clip's ridge misses (bright, sunlit):
        # σ = w / (2√3) peaks a bar of width w at its middle, not its edges
        if wide > max(scales) and float(np.median(rn[fe.stem])) < 0.5:
            trunk_ridge = ridge_filter(fe.bark, (wide,))
            rn_frame = np.maximum(rn_frame, normalized(trunk_ridge, mask)[0])
        rn = np.maximum(rn, rn_frame)
    return rn, fe, trunk_ridge


def trace_cost(params: TraceParams, mask: np.ndarray, rn: np.ndarray, ridge: np.ndarray, sky: np.ndarray,
               background: np.ndarray | None) -> np.ndarray:
    """Step 3 of the module docstring: ``(h, w)`` cost per pixel, low on ridges, higher in
    foliage, highest on sky and on frame 1's background."""
    cost = 1.0 + params.foliage_cost * (1.0 - rn) ** 2 + params.sky_cost * sky
    if background is not None:
        cost = cost + params.background_cost * background
    rmax = float(ridge[mask].max()) if mask.any() else 0.0
    if rmax > 1e-6:   # a small pull toward the ridge crest (no plateau across a wide trunk)
        cost -= 0.5 * np.sqrt(ridge / rmax)
    return cost


def _palm(params: TraceParams, mask: np.ndarray, tree: np.ndarray, cost: np.ndarray, base: tuple[int, int],
          size: float) -> tuple[np.ndarray, np.ndarray] | None:
    """A palm's trunk and fronds (:mod:`.palm`) as ``(parents, pos)`` working px, or None."""
    from .palm import palm_pixel_tree
    got = palm_pixel_tree(cost, mask, tree & mask, base, size)
    if got is None:
        return None
    parent_px, _, tips = got
    h, w = mask.shape
    return simplify_tree(parent_px, base[1] * w + base[0], set(tips), w, params.spacing * size,
                         params.min_spur * size)


def _trace_paths(params: TraceParams, mask: np.ndarray, rn: np.ndarray, ridge: np.ndarray,
                 sky: np.ndarray, background: np.ndarray | None, hier: Hierarchy, p0: np.ndarray,
                 twigs: np.ndarray, base: tuple[int, int], size: float,
                 progress: ProgressFn | None, trunk_top: int | None = None,
                 leader: tuple[int, int] | None = None, cost: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Steps 3–5 of the module docstring on working-resolution maps; returns (parents, pos px).
    ``trunk_top``: row of a hidden trunk's top (:func:`hidden_trunk`); the paths then all rise
    from the base up the column above it to that row (walls on both sides), so the crown
    branches from the trunk's top, foliage below it hanging from the limbs. ``leader`` (x, y):
    a conifer's top; a straight leader from the base to it costs less than any crest, so every
    branch climbs it and leaves it about level (whorls), and the top is a target. ``cost``: the
    :func:`trace_cost` map when already made (it is not changed)."""
    h, w = mask.shape
    bx, by = base
    cost = trace_cost(params, mask, rn, ridge, sky, background) if cost is None else cost.copy()
    graph_mask = mask
    if trunk_top is not None and trunk_top < by:
        graph_mask = mask.copy()
        rows = slice(trunk_top, by + 1)
        cost[rows, bx] = 0.3                                    # the trunk: cheaper than any crest
        wall = int(np.ceil(params.merge_radius * size)) + 2     # wider than a path's merge radius
        for side in (-1, 1):                                    # walls: nothing leaves it below its top
            xs = [bx + side * d for d in range(1, wall + 1) if 0 <= bx + side * d < w]
            graph_mask[trunk_top + 2:, xs] = False
        graph_mask[by + 1:, bx] = False                         # nor under the base
        graph_mask[rows, bx] = True
    if leader is not None:
        line = np.zeros((h, w), np.uint8)
        cv2.polylines(line, [leader_curve(ridge, mask, (bx, by), leader).round().astype(np.int32)], False, 1, 1)
        cost[(line > 0) & mask] = 0.3
    G = grid_graph(cost.astype(np.float64), graph_mask)
    root = by * w + bx
    dist, pred = dijkstra(G, directed=False, indices=root, return_predecessors=True)
    report(progress, "skeleton", 0.5)

    # targets: cluster centroids and twig ends (foliage), where clusters meet, far ends of ridges
    reach = np.isfinite(dist).reshape(h, w)
    ry, rx = np.nonzero(reach)

    def snap(points: np.ndarray) -> np.ndarray:
        """Nearest reachable pixel (flat index) for each of ``points (K, 2)`` working px."""
        if len(points) == 0:
            return np.zeros(0, int)
        from scipy.spatial import cKDTree
        _, j = cKDTree(np.stack([rx, ry], 1)).query(points)
        return ry[j] * w + rx[j]

    centroids = np.array([p0[m].mean(0) for m in hier.members if len(m)]).reshape(-1, 2)
    foliage = snap(np.vstack([centroids, twigs]))
    # a foliage target on visible bark is no twig end: the branch under it is traced already
    foliage = foliage[rn.ravel()[foliage] < 0.5]
    keep = set(int(t) for t in foliage)
    targets = [int(t) for t in foliage]
    targets += [int(t) for t in snap(np.array(list(meeting_points(hier, p0).values())).reshape(-1, 2))]
    thr = max(0.3, float(np.percentile(rn[mask], 90)))
    targets += ridge_targets((rn > thr) & mask, root, dist, params.min_fragment * size)
    if leader is not None:
        targets += [int(t) for t in snap(np.array([leader], float))]
    targets = [t for t in targets if t != root and np.isfinite(dist[t])]
    if trunk_top is not None:
        # foliage in front of a hidden trunk, or under its top closer to it than half its depth
        # below the top, is no branch end: a branch to it would hang down along the trunk
        tx, ty = np.array(targets, int) % w, np.array(targets, int) // w
        hang = (ty > trunk_top) & (np.abs(tx - bx) < 0.5 * (ty - trunk_top) + 1)
        targets = [t for t, drop in zip(targets, hang) if not drop]
    # merge radius: a share of the tree's size, wider across thick visible branches
    body = ((rn > 0.3) & mask).astype(np.uint8)
    half_width = cv2.distanceTransform(body, cv2.DIST_L2, 3)
    radius = np.maximum(params.merge_radius * size, 1.5 * half_width + 1.0)
    parent_px = path_tree(pred, dist, cost.ravel(), root, targets, w, np.round(radius).astype(int).ravel())
    parents, pos = simplify_tree(parent_px, root, keep, w, params.spacing * size, params.min_spur * size)
    return parents, pos


def traced_skeleton(tracks: Tracks, hier: Hierarchy, outline: Outline, maps: AppearanceMaps,
                    params: TraceParams | None = None,
                    progress: ProgressFn | None = None, tree_mask: np.ndarray | None = None,
                    form: str = "broadleaf") -> Skeleton2D:
    """Trace the skeleton (see module docstring) and move its nodes with the tracks.
    ``tree_mask (H, W)`` frame 1's tree pixels at the outline's size (the foreground), which
    tells a crown that hides its trunk (:func:`hidden_trunk`; the outline when None). ``form``
    (:data:`..forms.TREE_FORMS`): a conifer's trunk runs on as its leader to the tree's top
    (:func:`leader_tip`), every branch leaving it."""
    params = params or TraceParams()
    f = maps.factor
    mask = maps.mask
    ys, _ = np.nonzero(mask)
    size = float(ys.max() - ys.min() + 1)                      # tree height, working px
    ev = bark_evidence(maps)
    ridge = ridge_filter(ev, params.ridge_scales)
    warnings = []
    rn, rscale = normalized(ridge, mask)
    background = bark1 = None
    trunk_ridge = None
    trunk_width = float("nan")          # frame px, measured for a wide trunk the clip misses
    if params.frame1:
        rn, fe, trunk_ridge = with_frame1(params, maps, rn, size)
        if fe is not None:
            background, bark1 = fe.background, fe.bark
            if trunk_ridge is not None:
                trunk_width = fe.trunk_width / f
    has_evidence = rscale > 1e-6 and float((rn > 0.3).sum()) > 0.02 * size * size / 10
    sky = sky_likeness(maps)
    if trunk_ridge is not None and bark1 is not None:   # a sunlit trunk: bright, steady, smooth, but bark
        sky = sky * (1.0 - bark1)
    tree = mask
    if tree_mask is not None:
        tree = cv2.resize(np.asarray(tree_mask, np.uint8), mask.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0
        tree &= mask
        share = float(tree.sum()) / max(float(mask.sum()), 1.0)
        if share < 0.05:
            warnings.append(f"frame 1's tree pixels cover {share:.0%} of the outline: the skeleton is "
                            "traced in the whole outline (draw the outline tighter round the tree)")
            tree = mask
    hidden = hidden_trunk(tree, params.base_width, params.hidden_trunk, mask)
    if trunk_ridge is not None:   # a wide trunk the clip misses: its base and crest on frame 1's ridge
        ridge = np.maximum(ridge / max(rscale, 1e-6), trunk_ridge / max(float(trunk_ridge[mask].max()), 1e-6))
    bx, by = trunk_base(ridge, ev, mask) if hidden is None else hidden[:2]
    if hidden is not None:
        warnings.append(f"the crown reaches the ground (at its base the tree is {hidden[3]:.0%} as wide as at "
                        f"its widest): the trunk is hidden, so it rises from the tree's lowest point up to "
                        f"{params.hidden_trunk:.0%} of the height")
    p0 = tracks.points[0] * f
    twigs, owner = foliage_targets(hier, p0, max(params.twig_tracks, len(hier.members[0]) // params.max_twigs))
    report(progress, "skeleton", 0.2)
    palm = cost = None
    if form == "palm" and hidden is None:
        cost = trace_cost(params, mask, rn, ridge, sky, background)
        palm = _palm(params, mask, tree, cost, (bx, by), size)
        if palm is None:
            warnings.append("no crown of fronds found above a trunk: the palm is traced as a broadleaf")
    if palm is not None:
        parents, pos = palm
    elif has_evidence:
        tip = leader_tip(tree, bx) if form == "conifer" and hidden is None else None
        parents, pos = _trace_paths(params, mask, rn, ridge, sky, background, hier, p0, twigs, (bx, by),
                                    size, progress, None if hidden is None else hidden[2], tip, cost)
    else:
        warnings.append("no bark visible between the leaves: the skeleton follows the motion "
                        "hierarchy with a straight trunk")
        parents, pos = hierarchy_geometry(hier, p0, np.array([bx, by], float), size, twigs, owner,
                                          params.spacing * size, None if hidden is None else hidden[2])
    report(progress, "skeleton", 0.7)
    parents, pos = binarize(parents, pos)
    if palm is None and hidden is None:     # a wide trunk measured on frame 1: up its middle, straight
        parents, pos = straighten_stem(parents, pos, trunk_width * f, mask, trunk_ridge)
    pos = pos / f
    fixed = np.zeros(len(parents), bool)
    fixed[0] = True
    mo = follow_tracks(pos, tracks, NODE_MOTION_SCALE * crown_scale(outline), fixed)
    report(progress, "skeleton", 1.0)
    return Skeleton2D(parents, mo.nodes, branching_level(parents), tracks.fps, "traced", warnings,
                      confidence=mo.confidence, times=tracks.times, hidden_trunk=hidden is not None,
                      limbs_seen=palm is not None or has_evidence, trunk_width_px=trunk_width)
