"""The crown envelope Ω (paper §3): a surface of revolution of the outline about the trunk's
axis, in plane coordinates (px from the trunk base, or metres once stored in a tree's
``meta["envelope"]``). The 3D lift keeps nodes inside it, leaves and twigs stop at it, and new
trees grow into one.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .meta import EnvelopeMeta
from .outline import Outline


@dataclass
class Envelope:
    """Surface of revolution Ω from the outline, in plane coordinates (px from the trunk base).

    ``z (H,)`` heights (ascending), ``centre (H,)`` x of the axis and ``radius (H,)`` at each.
    """

    z: np.ndarray
    centre: np.ndarray
    radius: np.ndarray
    depth_scale: float = 1.0       # the crown's depth / its width: 1 round, below 1 flatter (an ellipse)

    def at(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(centre, radius) interpolated at heights ``z``; radius 0 above and below the outline
        (beyond half a row: half a pixel for an outline's, not half a metre for one in metres)."""
        half = 0.5 * float(np.median(np.diff(self.z))) if len(self.z) > 1 else 0.5
        inside = (z >= self.z[0] - half) & (z <= self.z[-1] + half)
        c = np.interp(z, self.z, self.centre)
        r = np.where(inside, np.interp(z, self.z, self.radius), 0.0)
        return c, r

    def depth_limit(self, p: np.ndarray) -> np.ndarray:
        """Largest |depth| a point ``p (..., 3)`` may have at its x and height (NaN-free, ≥ 0)."""
        c, r = self.at(p[..., 2])
        return self.depth_scale * np.sqrt(np.maximum(r ** 2 - (p[..., 0] - c) ** 2, 0.0))

    def contains(self, p: np.ndarray, tol: float = 0.5) -> np.ndarray:
        """``(...)`` bool: inside Ω (with ``tol`` px of slack)."""
        c, r = self.at(p[..., 2])
        return np.hypot(p[..., 0] - c, p[..., 1] / self.depth_scale) <= r + tol

    def attractors(self, n: int) -> np.ndarray:
        """About ``n`` points ``(K, 3)`` spread evenly over Ω's lateral surface (area-weighted
        heights, golden-angle azimuths)."""
        dz = np.gradient(self.z) if len(self.z) > 1 else np.ones(1)
        area = 2 * np.pi * self.radius * np.abs(dz)
        if area.sum() <= 0:
            return np.zeros((0, 3))
        cdf = np.cumsum(area) / area.sum()
        u = (np.arange(n) + 0.5) / n
        z = np.interp(u, cdf, self.z)
        c, r = self.at(z)
        theta = np.arange(n) * np.pi * (3 - np.sqrt(5))
        pts = np.stack([c + r * np.cos(theta), self.depth_scale * r * np.sin(theta), z], axis=1)
        return pts[r > 0]


def envelope_to_meta(env: Envelope, scale: float) -> EnvelopeMeta:
    """Ω as JSON-able lists in metres (``scale`` metres per px), for :attr:`Tree3D.meta`."""
    return {"z": (env.z * scale).round(6).tolist(), "centre": (env.centre * scale).round(6).tolist(),
            "radius": (env.radius * scale).round(6).tolist()}


def envelope_from_meta(meta: Mapping[str, Any]) -> Envelope | None:
    """The envelope stored by :func:`envelope_to_meta` in a tree's ``meta["envelope"]`` (metres),
    or None when the tree has none."""
    e = meta.get("envelope")
    if not e:
        return None
    return Envelope(np.asarray(e["z"], float), np.asarray(e["centre"], float), np.asarray(e["radius"], float))


def envelope_from_outline(outline: Outline, base_px: np.ndarray) -> Envelope:
    """Ω from the outline mask: per image row, centre = middle of the row's extent and radius =
    half its width, in plane coordinates relative to ``base_px`` (x, y) pixels."""
    mask = outline.mask
    rows = np.flatnonzero(mask.any(1))
    w = mask.shape[1]
    cols = np.arange(w)
    m = mask[rows]
    left = np.where(m, cols, w).min(1)
    right = np.where(m, cols, -1).max(1)
    z = base_px[1] - rows.astype(float)
    centre = 0.5 * (left + right) - base_px[0]
    radius = 0.5 * (right - left + 1)
    order = np.argsort(z)
    return Envelope(z[order], centre[order], radius[order])
