"""A palm's fronds as wide as the video shows them (issue 31: a real storm palm rendered as an
invisible frond crown, its leaflets a few pixels long at the video's size).

:func:`.leaf_clusters.frond_template` lays a stretch of frond's leaflets in pairs along its bone,
each ``leaf_size`` long (0.6–1.0 of it along the stretch), pointing 35° forward and drooping 20°:
seen from the front a leaflet reaches ``leaf_size · cos 35° · cos 20° · 0.85`` (mean) to its side
of the midrib. Frame 1's foreground says how far a frond's pixels reach from its midrib: the
largest distance to the foreground's edge near each stretch's centre (its half-width). The
leaflets are made that long, so a frond covers what the video shows.
"""
from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from ..tree3d import LeafClusters, plane_to_image

#: a leaflet's reach to its side of the midrib per unit of ``leaf_size`` (frond_template's angles,
#: the mean of its 0.6–1.0 length profile)
REACH = float(np.cos(np.radians(35.0)) * np.cos(np.radians(20.0)) * 0.85)
#: the window round a stretch's centre searched for its midrib, a share of the stretch's radius
WINDOW = 0.15
#: the measured length is kept within these multiples of the template's own
LIMITS = (1.0, 6.0)


def frond_half_width_px(leaves: LeafClusters, base_px: np.ndarray, scale: float,
                        foreground: np.ndarray) -> np.ndarray:
    """``(S,)`` px: each frond stretch's half-width in frame 1, the largest distance to the edge of
    ``foreground (H, W)`` bool within ``WINDOW`` of its radius round its centre (0 outside the
    frame or the foreground). ``base_px`` the tree's base in frame-1 px, ``scale`` metres per px."""
    fg = np.asarray(foreground, np.uint8)
    dist = cv2.distanceTransform(fg, cv2.DIST_L2, 5)
    r = max(1, int(round(WINDOW * leaves.radius / scale)))
    dist = cv2.dilate(dist, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))   # max in the window
    px = plane_to_image(np.asarray(leaves.pos, np.float64) / scale, np.asarray(base_px, float))
    x, y = np.round(px[:, 0]).astype(int), np.round(px[:, 1]).astype(int)
    inside = (x >= 0) & (x < fg.shape[1]) & (y >= 0) & (y < fg.shape[0])
    out = np.zeros(len(px), np.float32)
    out[inside] = dist[y[inside], x[inside]]
    return out


def fit_fronds(leaves: LeafClusters | None, base_px: np.ndarray, scale: float,
               foreground: np.ndarray | None) -> tuple[LeafClusters | None, dict | None]:
    """``leaves`` (shape ``"frond"``) with ``leaf_size`` set so a leaflet reaches the median
    half-width frame 1 shows (:func:`frond_half_width_px`) over the outer half of the stretches
    on the foreground,
    within :data:`LIMITS` of its own, and what was measured (``width_px`` the fronds' median width
    in frame 1, ``leaf_size_m`` and ``was_m`` the leaflets' length after and before, ``why``);
    unchanged (None) without a foreground or fronds."""
    if leaves is None or foreground is None or leaves.shape != "frond" or leaves.count == 0:
        return leaves, None
    hw = frond_half_width_px(leaves, base_px, scale, foreground)
    # the outer half of the stretches (farther from the crown's middle than their median): where
    # fronds overlap round the crown's top the foreground is one mass, wider than any frond
    xz = np.asarray(leaves.pos, np.float64)[:, [0, 2]]
    d = np.linalg.norm(xz - np.median(xz, axis=0), axis=1)
    hw = hw[(hw > 0) & (d >= np.median(d))]
    if len(hw) == 0:
        return leaves, None
    want = float(np.median(hw)) * scale / REACH
    size = float(np.clip(want, LIMITS[0] * leaves.leaf_size, LIMITS[1] * leaves.leaf_size))
    width = 2 * float(np.median(hw))
    note = {"width_px": round(width, 1), "leaf_size_m": round(size, 4), "was_m": round(float(leaves.leaf_size), 4),
            "why": f"fronds {width:.0f} px wide in frame 1: leaflets {size:.2f} m long (were {leaves.leaf_size:.2f} m)"}
    return dataclasses.replace(leaves, leaf_size=size), note
