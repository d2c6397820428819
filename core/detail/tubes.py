"""The thick branches as frame 1 shows them: each edge a line as wide as its tube (one raster for
the bark's own pixels, :func:`.albedo.trunk_pixels`, and the bark the leaves leave out,
:func:`.leaf_seeds.bark_pixels`)."""
from __future__ import annotations

import cv2
import numpy as np

from ..topology import edges_of


def tube_pixels(shape: tuple[int, int], parents: np.ndarray, nodes_px: np.ndarray, radius_px: np.ndarray,
                share: float, width: float) -> np.ndarray:
    """``(H, W)`` bool: every edge (parent → child of ``parents (N,)``) whose child's radius
    ``radius_px (N,)`` is at least ``share`` of the widest (NaN radii count as 0), drawn between
    ``nodes_px (N, 2)`` frame-1 px as a line ``width`` × that radius wide (at least 1 px), at
    1/16 px precision."""
    out = np.zeros(shape, np.uint8)
    r = np.asarray(radius_px, np.float64)
    e = edges_of(np.asarray(parents))
    if len(r) == 0 or len(e) == 0 or not np.isfinite(r).any():
        return out.astype(bool)
    e = e[np.nan_to_num(r[e[:, 1]]) >= share * float(np.nanmax(r))]
    ends = np.round(np.asarray(nodes_px, np.float64)[e] * 16).astype(np.int64)          # (E, 2, 2)
    for (a, b), w in zip(ends, width * r[e[:, 1]]):
        cv2.line(out, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), 1, max(1, int(round(w))), cv2.LINE_8, 4)
    return out.astype(bool)
