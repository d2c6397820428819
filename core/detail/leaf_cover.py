"""How much of frame 1's foliage the leaf clusters cover, and where to add clusters so they cover
it (issue 19: crowns as full as the video's).

Clusters start at the Harris corners and the fill seeds (:mod:`.leaf_seeds`); each is ``cards``
leaf cards in a sphere of its radius, so between them the video's crown can show through the
render as sky. :func:`card_footprint` draws the cards of frame 1 seen like the video
(orthographic, front view): each card's blade, a hexagon inside its quad, the procedural leaf's
outline. :func:`uncovered_sites` then picks new cluster centres where the foliage is still
uncovered, farthest from anything covered first, one per cluster radius.
"""
from __future__ import annotations

import cv2
import numpy as np

from ..tree3d import plane_to_image
from .leaf_clusters import axis_frames, template

#: a card's blade inside its quad, in the card's (u across, v along) coordinates: stem, widest
#: at 30–70 %, tip (the procedural leaf of the materials; a user's leaf image is similar)
BLADE_UV = np.array([[0.5, 0.0], [0.1, 0.3], [0.1, 0.7], [0.5, 1.0], [0.9, 0.7], [0.9, 0.3]])


def card_footprint(shape: tuple[int, int], pos: np.ndarray, axis: np.ndarray, size: np.ndarray,
                   radius: float, leaf_size: float, cards: int, seed: int, base_px: np.ndarray,
                   scale: float, kind: str = "cluster") -> np.ndarray:
    """``(H, W)`` bool: where the leaf blades of clusters at ``pos (S, 3)`` metres (the lift's
    plane frame: x right, y depth, z up), main ``axis (S, 3)``, relative ``size (S,)``, cover
    frame 1 (``base_px`` the trunk base in px, ``scale`` metres per px), with the cluster
    template of :func:`.leaf_clusters.leaf_mesh` (``cards``, ``radius``, ``leaf_size``, ``seed``,
    ``kind`` the clusters' shape)."""
    out = np.zeros(shape, np.uint8)
    if len(pos) == 0:
        return out.astype(bool)
    tco, _ = template(kind, cards, radius, leaf_size, seed)
    quad = tco.reshape(-1, 4, 3)                                      # (C, 4, 3): stem L, R, tip R, L
    u, v = BLADE_UV[:, 0][:, None], BLADE_UV[:, 1][:, None]
    # bilinear in the quad: (1-v)·((1-u)·c0 + u·c1) + v·((1-u)·c3 + u·c2)
    blade = ((1 - v) * (1 - u))[None] * quad[:, None, 0] + ((1 - v) * u)[None] * quad[:, None, 1] \
        + (v * u)[None] * quad[:, None, 2] + (v * (1 - u))[None] * quad[:, None, 3]   # (C, 6, 3)
    R = axis_frames(np.asarray(axis, np.float64), seed, kind == "frond")              # (S, 3, 3)
    world = np.asarray(pos, np.float64)[:, None, None] + np.einsum(
        "sij,cvj->scvi", R, blade) * np.asarray(size, np.float64)[:, None, None, None]
    px = plane_to_image(world / scale, np.asarray(base_px, np.float64))              # (S, C, 6, 2)
    polys = np.round(px.reshape(-1, len(BLADE_UV), 2) * 16).astype(np.int32)
    cv2.fillPoly(out, list(polys), 1, cv2.LINE_8, 4)                  # 4 fractional bits
    return out.astype(bool)


def uncovered_sites(target: np.ndarray, covered: np.ndarray, spacing_px: float,
                    min_px: float = 1.5, deepest_first: bool = False) -> np.ndarray:
    """Centres ``(E, 2)`` px for new clusters: in ``target (H, W)`` (the foliage) but not
    ``covered (H, W)``, one per ``spacing_px`` square cell, at the cell's uncovered pixel deepest
    inside the uncovered part (its distance transform, at least ``min_px``: slivers between
    cards are not holes); row by row, or the deepest first with ``deepest_first``."""
    hole = (np.asarray(target, bool) & ~np.asarray(covered, bool)).astype(np.uint8)
    if not hole.any():
        return np.zeros((0, 2), np.float32)
    dist = cv2.distanceTransform(hole, cv2.DIST_L2, 3)
    ys, xs = np.nonzero(dist >= min_px)
    if len(ys) == 0:
        return np.zeros((0, 2), np.float32)
    order = np.argsort(-dist[ys, xs], kind="stable")
    ys, xs = ys[order], xs[order]
    cell = max(1.0, float(spacing_px))                    # one centre per cell: its deepest pixel
    cy, cx = (ys / cell).astype(np.int64), (xs / cell).astype(np.int64)
    _, first = np.unique(cy * (int(cx.max()) + 1) + cx, return_index=True)
    if deepest_first:
        first = np.sort(first)
    return np.stack([xs[first], ys[first]], 1).astype(np.float32)
