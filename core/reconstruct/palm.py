"""A palm's skeleton (issue 19, form ``palm``): one trunk, curved as traced, and a crown of fronds
from its top — not a web of twigs through the crown.

1. The crown: frame 1's tree pixels above the lowest row where they are wider than
   :data:`CROWN_WIDTH` trunk widths (the bare trunk below is narrow).
2. The crown's top ``T`` (where the fronds start): at the median row of the crown's pixels — a
   crown of fronds rising and drooping from its top is balanced about it — on the trunk's line.
3. The trunk: the cheapest path (the trace's cost: ridges cheap, sky dear) from the base to ``T``.
4. The fronds: geodesic distance from ``T`` through the crown's pixels; round the crown's outline
   it peaks at every frond's end (:func:`frond_ends`: :data:`FROND_PROMINENCE` above the notches
   beside it, at least :data:`MIN_FROND` of the longest frond); each frond is the cheapest path from ``T`` to its end
   along the middle of the crown's pixels (the distance transform). All fronds start at ``T``.
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.sparse.csgraph import dijkstra

from .pixel_graph import grid_graph

#: the crown starts at the lowest row this many trunk widths wide
CROWN_WIDTH = 3.0
#: a frond's end stands this share of the tree's height above the notches on either side of it
FROND_PROMINENCE = 0.02
#: a frond at least this share of the longest one's length (shorter: a leaflet, not a frond)
MIN_FROND = 0.3


def crown_top(tree: np.ndarray, base: tuple[int, int]) -> tuple[np.ndarray, int, float] | None:
    """``(crown (h, w) bool, T_y, trunk width)``: the crown's pixels of ``tree (h, w)`` (above the
    lowest row :data:`CROWN_WIDTH` trunk widths wide), the row of its top (their median row) and
    the trunk's width (px, at the base), or None when there is no crown above a trunk."""
    width = tree.sum(1)
    bx, by = base
    trunk_w = float(np.median(width[max(by - 10, 0):by + 1][width[max(by - 10, 0):by + 1] > 0])) \
        if (width[max(by - 10, 0):by + 1] > 0).any() else 1.0
    wide = np.flatnonzero(width > CROWN_WIDTH * max(trunk_w, 1.0))
    if len(wide) == 0:
        return None
    crown = tree & (np.arange(tree.shape[0]) <= wide.max())[:, None]
    ys = np.nonzero(crown)[0]
    if len(ys) < 20:
        return None
    return crown, int(np.median(ys)), trunk_w


def frond_ends(crown: np.ndarray, top: tuple[int, int], size: float) -> tuple[np.ndarray, np.ndarray]:
    """``(ends (K, 2) px, geodesic (h, w))``: where fronds end, and the geodesic distance from
    ``top`` through ``crown`` (inf outside). Walking round the crown's outline, the geodesic
    distance rises to every frond's end and falls back into the notch before the next: ends are
    its peaks that stand :data:`FROND_PROMINENCE` of the height above both notches and reach
    :data:`MIN_FROND` of the farthest."""
    from scipy.signal import find_peaks
    h, w = crown.shape
    G = grid_graph(np.ones((h, w)), crown)
    geo = dijkstra(G, directed=False, indices=top[1] * w + top[0]).reshape(h, w)
    finite = np.isfinite(geo)
    if not finite.any() or geo[finite].max() <= 0:
        return np.zeros((0, 2), int), geo
    reach = (finite & crown).astype(np.uint8)
    contours, _ = cv2.findContours(reach, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(contours, key=len)[:, 0]                       # (M, 2) x, y round the outline
    g = geo[c[:, 1], c[:, 0]]
    g = np.where(np.isfinite(g), g, 0.0)
    M = len(g)
    ring = np.concatenate([g, g, g])                       # closed: a peak may straddle the start
    peaks, _ = find_peaks(ring, prominence=FROND_PROMINENCE * size, height=MIN_FROND * float(g.max()))
    peaks = np.unique(peaks[(peaks >= M) & (peaks < 2 * M)] - M)
    return c[peaks].astype(int).reshape(-1, 2), geo


def palm_pixel_tree(cost: np.ndarray, mask: np.ndarray, tree: np.ndarray, base: tuple[int, int],
                    size: float) -> tuple[dict[int, int], int, list[int]] | None:
    """The palm as a pixel tree ``{pixel: parent pixel}`` (flat indices of ``(h, w)``) rooted at
    the base, the top's pixel and the frond ends' pixels; ``cost (h, w)`` the trace's per-pixel
    cost inside ``mask`` (the outline), ``tree`` frame 1's tree pixels. None when no crown or no
    frond is found (the caller traces it as a broadleaf)."""
    h, w = mask.shape
    got = crown_top(tree, base)
    if got is None:
        return None
    crown, ty, trunk_w = got
    bx, by = base
    # the trunk: cheapest path from the base to the top's row, then along the trunk's line
    G = grid_graph(cost.astype(np.float64), mask)
    dist, pred = dijkstra(G, directed=False, indices=by * w + bx, return_predecessors=True)
    row = np.flatnonzero(np.isfinite(dist.reshape(h, w)[ty]) & crown[ty])
    if len(row) == 0:
        return None
    col = row[np.argmin(dist.reshape(h, w)[ty, row])]
    top = int(ty * w + col)
    parent: dict[int, int] = {}
    u = top
    while u != by * w + bx and pred[u] >= 0:
        parent[u] = int(pred[u])
        u = int(pred[u])
    trunk = set(parent) | {by * w + bx}
    # the fronds: the tree's pixels joined to the top once the bare trunk below it is taken out
    # (drooping fronds hang below the crown's wide rows, beside the trunk)
    bare = np.zeros((h, w), np.uint8)
    half = cv2.distanceTransform(tree.astype(np.uint8), cv2.DIST_L2, 3)
    path = np.array([[p // w, p % w] for p in trunk], int).reshape(-1, 2)
    low = path[path[:, 0] > ty + (ty - int(np.flatnonzero(crown.any(1)).min()))]   # well below the top
    k = 2 * int(np.ceil(np.percentile(half[low[:, 0], low[:, 1]], 90) if len(low) else 0.5 * trunk_w)) + 5
    tyx = path[path[:, 0] > ty + k]
    bare[tyx[:, 0], tyx[:, 1]] = 1
    bare = cv2.dilate(bare, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))) > 0
    frond_mask = tree & ~bare
    frond_mask[ty, col] = True
    _, lab = cv2.connectedComponents(frond_mask.astype(np.uint8), connectivity=8)
    frond_mask = lab == lab[ty, col]
    ends, _ = frond_ends(frond_mask, (int(col), ty), size)
    dt = cv2.distanceTransform(frond_mask.astype(np.uint8), cv2.DIST_L2, 3)
    Gf = grid_graph(1.0 / (0.5 + dt.astype(np.float64)), frond_mask)   # along a frond's middle
    _, fpred = dijkstra(Gf, directed=False, indices=top, return_predecessors=True)
    tips = []
    for x, y in ends:
        v = int(y * w + x)
        if fpred[v] < 0:
            continue
        tips.append(v)
        while v != top and v not in parent:
            parent[v] = int(fpred[v])
            v = int(fpred[v])
    return (parent, top, tips) if tips else None
