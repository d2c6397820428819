"""The default ``traced`` 2D skeleton: branches traced in the image, hierarchy as the crown's map.

1. Bark evidence ``E = dark · steady``: the share of frames a pixel is dark times
   ``exp(-std / s)`` (foliage flickers, bark does not), from :class:`AppearanceMaps`.
2. Ridges: multi-scale Hessian ridge filter of E (``σ² · max(0, −λ_min)``, max over scales).
3. A cost per pixel, low on ridges, higher in foliage, highest on bright, steady, smooth
   pixels (sky seen through the crown); pixels outside the outline are not in the graph.
4. Shortest paths (Dijkstra, 8-connected) from the trunk base to targets: the far ends of
   traced ridge fragments and the centroids of the hierarchy's leaf clusters. The union of the
   paths is a tree: internal hierarchy clusters land where their children's paths meet.
5. The pixel tree is cut into chains between the root, branch points and tips, resampled every
   ``spacing`` px, and made binary.

When no bark evidence exists (a dense, front-lit crown), the same construction runs with the
hierarchy's clusters as targets and a trunk prior (a straight climb from the base), so a valid
skeleton always comes out.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from .appearance import AppearanceMaps
from .hierarchy import Hierarchy
from .outline import Outline
from .progress import ProgressFn, report
from .skeleton2d import Skeleton2D, binarize, branching_level, children_lists, crown_scale, node_motion
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


def bark_evidence(maps: AppearanceMaps) -> np.ndarray:
    """``E (h, w)`` in [0, 1]: dark in most frames × steady over time, zero outside the outline."""
    inside = maps.mask
    s = float(np.median(maps.std[inside])) if inside.any() else 1.0
    steady = np.exp(-maps.std / max(s, 1e-3))
    e = maps.dark * steady
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


def sky_likeness(maps: AppearanceMaps) -> np.ndarray:
    """``(h, w)`` in [0, 1]: bright relative to the tree, steady, and smooth in space."""
    inside = maps.mask
    mean = maps.mean
    lo, hi = (np.percentile(mean[inside], [50, 97]) if inside.any() else (0.0, 255.0))
    bright = np.clip((mean - lo) / max(hi - lo, 1.0), 0, 1)
    gx = cv2.Sobel(maps.first.mean(-1).astype(np.float32), cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(maps.first.mean(-1).astype(np.float32), cv2.CV_32F, 0, 1)
    grad = cv2.GaussianBlur(np.hypot(gx, gy), (0, 0), 2.0)
    gs = float(np.median(grad[inside])) if inside.any() else 1.0
    smooth = np.exp(-grad / max(gs, 1e-3))
    sky = bright * smooth
    return cv2.GaussianBlur(sky.astype(np.float32), (0, 0), 1.0)


def grid_graph(cost: np.ndarray, inside: np.ndarray) -> sp.csr_matrix:
    """8-connected graph of ``inside`` pixels, edge weight = step length × mean cost."""
    h, w = cost.shape
    idx = np.arange(h * w).reshape(h, w)
    rows, cols, wts = [], [], []
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        ys = slice(0, h - dy)
        xs = slice(max(0, -dx), w - max(0, dx))
        ys2 = slice(dy, h)
        xs2 = slice(max(0, dx), w - max(0, -dx) if dx < 0 else w)
        a, b = idx[ys, xs], idx[ys2, xs2]
        ok = inside[ys, xs] & inside[ys2, xs2]
        c = 0.5 * (cost[ys, xs] + cost[ys2, xs2]) * np.hypot(dy, dx)
        rows.append(a[ok]); cols.append(b[ok]); wts.append(c[ok])
    r, c, wv = np.concatenate(rows), np.concatenate(cols), np.concatenate(wts)
    g = sp.coo_matrix((wv, (r, c)), shape=(h * w, h * w)).tocsr()
    return g + g.T


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


def path_tree(pred: np.ndarray, root: int, targets: list[int]) -> dict[int, int]:
    """Union of predecessor paths from each target back to ``root``: {pixel: parent pixel}."""
    parent: dict[int, int] = {}
    for t in targets:
        u = t
        while u != root and u not in parent and u >= 0:
            p = int(pred[u])
            if p < 0:
                break
            parent[u] = p
            u = p
    return parent


def simplify_tree(parent: dict[int, int], root: int, keep: set[int], width: int,
                  spacing: float, min_spur: float) -> tuple[np.ndarray, np.ndarray]:
    """Pixel tree → node tree: root, branch points, tips and chain nodes every ``spacing`` px.

    Side branches shorter than ``min_spur`` px that end in no ``keep`` pixel are dropped.
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
    reach = {}
    has_keep = {}
    for u in reversed(order):
        ch = kids.get(u, [])
        reach[u] = max((reach[c] + np.linalg.norm(xy(c) - xy(u)) for c in ch), default=0.0)
        has_keep[u] = (u in keep) or any(has_keep[c] for c in ch)

    parents, pos = [-1], [xy(root)]
    stack = [(root, 0, 0.0)]   # (pixel, node index of last emitted ancestor, arc length since it)
    while stack:
        u, last, run = stack.pop()
        ch = [c for c in kids.get(u, []) if has_keep[c] or reach[c] >= min_spur]
        for c in ch:
            step = float(np.linalg.norm(xy(c) - xy(u)))
            r = run + step
            n_kids = len([g for g in kids.get(c, []) if has_keep[g] or reach[g] >= min_spur])
            if n_kids != 1 or r >= spacing:
                parents.append(last)
                pos.append(xy(c))
                stack.append((c, len(pos) - 1, 0.0))
            else:
                stack.append((c, last, r))
    return np.array(parents, np.int32), np.array(pos)


def trunk_base(evidence: np.ndarray, mask: np.ndarray) -> tuple[int, int]:
    """(x, y) working px of the trunk base: bottom rows of the outline, darkest-steadiest column."""
    ys, xs = np.nonzero(mask)
    ybot = ys.max()
    band = max(2, int(0.03 * (ybot - ys.min() + 1)))
    rows = slice(max(ybot - band, 0), ybot + 1)
    col = evidence[rows].sum(0) * mask[rows].any(0)
    if col.max() <= 0:
        row = xs[ys == ybot]
        return int(round(row.mean())), int(ybot)
    prof = np.convolve(col, np.ones(5) / 5, mode="same")
    x = int(np.argmax(prof))
    yy = np.flatnonzero(mask[:, x])
    return x, int(yy.max()) if len(yy) else int(ybot)


def traced_skeleton(tracks: Tracks, hier: Hierarchy, outline: Outline, maps: AppearanceMaps,
                    params: TraceParams | None = None,
                    progress: ProgressFn | None = None) -> Skeleton2D:
    """Trace the skeleton (see module docstring) and move its nodes with the tracks."""
    params = params or TraceParams()
    f = maps.factor
    mask = maps.mask
    h, w = mask.shape
    ys, _ = np.nonzero(mask)
    size = float(ys.max() - ys.min() + 1)                      # tree height, working px
    ev = bark_evidence(maps)
    ridge = ridge_filter(ev, params.ridge_scales)
    inside_r = ridge[mask]
    warnings = []
    rscale = float(np.percentile(inside_r, 99)) if inside_r.size else 0.0
    rn = np.clip(ridge / rscale, 0, 1) if rscale > 1e-6 else np.zeros_like(ridge)
    has_evidence = rscale > 1e-6 and float((rn > 0.3).sum()) > 0.02 * size * size / 10
    sky = sky_likeness(maps)
    cost = 1.0 + params.foliage_cost * (1.0 - rn) ** 2 + params.sky_cost * sky
    bx, by = trunk_base(ev, mask)
    if not has_evidence:
        warnings.append("no bark visible between the leaves: skeleton follows the motion hierarchy "
                        "with a straight trunk")
        cost = 1.0 + params.foliage_cost * np.ones_like(cost) + params.sky_cost * sky
        # trunk prior: cheap vertical corridor above the base
        xx = np.arange(w)[None, :]
        corridor = np.exp(-((xx - bx) ** 2) / (2 * (0.03 * size) ** 2)) * (np.arange(h)[:, None] > by - 0.35 * size)
        cost = cost - params.foliage_cost * corridor
    report(progress, "skeleton", 0.2)
    G = grid_graph(cost.astype(np.float64), mask)
    root = by * w + bx
    dist, pred = dijkstra(G, directed=False, indices=root, return_predecessors=True)
    report(progress, "skeleton", 0.5)

    # targets: leaf-cluster centroids (snapped into the outline) and far ends of ridge fragments
    p0 = tracks.points[0] * f
    reach = np.isfinite(dist).reshape(h, w)
    ry, rx = np.nonzero(reach)
    targets, keep = [], set()
    for c in hier.leaves:
        m = hier.members[c]
        if len(m) == 0:
            continue
        cx, cy = p0[m].mean(0)
        j = np.argmin((rx - cx) ** 2 + (ry - cy) ** 2)
        t = int(ry[j] * w + rx[j])
        targets.append(t)
        keep.add(t)
    if has_evidence:
        thr = max(0.3, float(np.percentile(rn[mask], 90)))
        targets += ridge_targets((rn > thr) & mask, root, dist, params.min_fragment * size)
    targets = [t for t in targets if t != root and np.isfinite(dist[t])]
    parent_px = path_tree(pred, root, targets)
    parents, pos = simplify_tree(parent_px, root, keep, w, params.spacing * size, params.min_spur * size)
    report(progress, "skeleton", 0.7)
    parents, pos = binarize(parents, pos)
    pos = pos / f
    fixed = np.zeros(len(parents), bool)
    fixed[0] = True
    nodes = node_motion(pos, tracks, 0.04 * crown_scale(outline), fixed)
    report(progress, "skeleton", 1.0)
    return Skeleton2D(parents, nodes, branching_level(parents), tracks.fps, "traced", warnings)
