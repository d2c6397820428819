"""Mean value coordinates (Floater 2003; Hormann & Floater 2006, "Mean value coordinates for arbitrary
planar polygons") and the image warp they define between two polygons with matching vertices.

For a point ``p`` and polygon vertices ``v_i`` (``s_i = v_i − p``, ``r_i = |s_i|``, ``A_i`` the signed
area ``det(s_i, s_{i+1}) / 2``, ``D_i = s_i · s_{i+1}``):

    tan(α_i / 2) = 2 A_i / (r_i r_{i+1} + D_i)                 (HF06 eq. 8, as sin α / (1 + cos α))
    w_i = (tan(α_{i−1} / 2) + tan(α_i / 2)) / r_i,   λ_i = w_i / Σ_j w_j        (HF06 eq. 6)

Signed angles make λ well defined for any simple polygon, convex or not, and for points outside
it; ``Σ λ_i v_i = p`` (linear precision) everywhere. Used by :mod:`.variations` to carry an
exemplar's pixels into a new contour (seed 000 §5.2).
"""
from __future__ import annotations

import cv2
import numpy as np

#: a point this close to a vertex or an edge (px²) is nudged off it
EPS = 1e-9
#: the warp is computed on a grid this many px apart and interpolated (it is smooth)
GRID = 4


def mvc_weights(pts: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Mean value coordinates ``(P, M)`` of points ``pts (P, 2)`` over polygon ``poly (M, 2)``
    (module docstring); each row sums to 1."""
    s = np.asarray(poly, np.float64)[None] - np.asarray(pts, np.float64)[:, None]      # (P, M, 2)
    r = np.maximum(np.hypot(s[..., 0], s[..., 1]), EPS)
    s1 = np.roll(s, -1, axis=1)
    r1 = np.roll(r, -1, axis=1)
    area2 = s[..., 0] * s1[..., 1] - s[..., 1] * s1[..., 0]                             # 2 A_i
    dot = (s * s1).sum(-1)                                                             # D_i
    den = r * r1 + dot
    tan_half = area2 / np.where(np.abs(den) < EPS, EPS, den)                           # tan(α_i / 2)
    w = (np.roll(tan_half, 1, axis=1) + tan_half) / r
    total = w.sum(1, keepdims=True)
    lam = w / np.where(np.abs(total) < EPS, EPS, total)
    # a point on an edge (or a vertex) has the edge's linear interpolation as its coordinates (the
    # limit of eq. 6 there; the formula itself is 0/0)
    on = (np.abs(area2) <= 1e-9 * r * r1) & (dot <= 0)
    hit = on.any(1)
    if hit.any():
        rows = np.nonzero(hit)[0]
        i = np.argmax(on[rows], axis=1)
        m = lam.shape[1]
        t = r[rows, i] / (r[rows, i] + r1[rows, i])
        lam[rows] = 0.0
        lam[rows, i] = 1.0 - t
        lam[rows, (i + 1) % m] += t
    return lam


def warp_map(target_poly: np.ndarray, source_poly: np.ndarray, shape: tuple[int, int],
             grid: int = GRID) -> np.ndarray:
    """``(H, W, 2)`` float32 source px for each target px of an image ``shape (H, W)``: the target
    pixel's mean value coordinates over ``target_poly (M, 2)`` applied to ``source_poly (M, 2)``
    (``p = Σ λ'_i v_i``, seed 000 §5.2), computed every ``grid`` px and interpolated bilinearly;
    ready for :func:`cv2.remap`."""
    h, w = shape
    gy, gx = np.mgrid[0:h + grid:grid, 0:w + grid:grid].astype(np.float64)
    pts = np.stack([gx.ravel(), gy.ravel()], 1)
    src = np.empty_like(pts)
    for a in range(0, len(pts), 8192):          # bounded memory: (8192, M) at a time
        src[a:a + 8192] = mvc_weights(pts[a:a + 8192], target_poly) @ np.asarray(source_poly, np.float64)
    coarse = src.reshape(gy.shape + (2,)).astype(np.float32)
    # bilinear between the grid's nodes: target px (x, y) sits at grid coordinate (x / grid, y / grid)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32) / np.float32(grid)
    return cv2.remap(coarse, xx, yy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
