"""The image as a graph for shortest paths: 8-connected pixels weighted by a per-pixel cost
(the traced skeleton's paths, a palm's trunk and fronds)."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


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
        rows.append(a[ok])
        cols.append(b[ok])
        wts.append(c[ok])
    r, c, wv = np.concatenate(rows), np.concatenate(cols), np.concatenate(wts)
    g = sp.coo_matrix((wv, (r, c)), shape=(h * w, h * w)).tocsr()
    return g + g.T
