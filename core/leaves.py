"""Stage 8 (start) — leaf seeds (paper Appendix B.1).

The Harris points of frame 1 inside the outline become seeds for leaf clusters. They are split in
two halves by intensity — dark seeds go behind the branches, bright ones in front (the shading of
a real crown) — each is attached to its nearest skeleton node, and gets a depth from that node's
3D position toward the back (dark) or the front (bright) of the crown envelope.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from .lift3d import Envelope
from .tree3d import image_to_plane


@dataclass
class LeafSeeds:
    """``pos2d (S, 2)`` frame-1 px; ``intensity (S,)`` grey 0..255; ``dark (S,)`` bool (behind);
    ``node (S,)`` attached skeleton node; ``pos3d (S, 3)`` px in the lift's plane frame."""

    pos2d: np.ndarray
    intensity: np.ndarray
    dark: np.ndarray
    node: np.ndarray
    pos3d: np.ndarray


def seed_intensity(gray: np.ndarray, points: np.ndarray, radius: float = 2.0) -> np.ndarray:
    """Mean grey level ``(S,)`` around each point ``(S, 2)`` px: a corner sits on an edge, so a
    single pixel says little about the leaf it belongs to."""
    blur = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), radius)
    x = np.clip(np.round(points[:, 0]).astype(int), 0, gray.shape[1] - 1)
    y = np.clip(np.round(points[:, 1]).astype(int), 0, gray.shape[0] - 1)
    return blur[y, x]


def split_dark_bright(intensity: np.ndarray) -> np.ndarray:
    """``(S,)`` bool, True for the darker half (below the median), as the paper splits seeds."""
    return intensity < np.median(intensity)


def leaf_seeds(points: np.ndarray, gray: np.ndarray, nodes2d: np.ndarray, nodes3d: np.ndarray,
               base_px: np.ndarray, envelope: Envelope, seed: int = 0) -> LeafSeeds:
    """Seeds from frame-1 Harris ``points (S, 2)`` on the grey frame ``gray``; skeleton frame-1
    ``nodes2d (N, 2)`` px and lifted ``nodes3d (N, 3)`` (plane frame, px); depth toward the back of
    the envelope for dark seeds and the front for bright ones, a seeded share of the way (0.3–0.9)
    from the node's depth (clipped into the envelope at the seed) to the envelope's surface."""
    intensity = seed_intensity(gray, points)
    dark = split_dark_bright(intensity)
    _, node = cKDTree(nodes2d).query(points)
    p3 = image_to_plane(points.astype(np.float64), base_px)
    limit = envelope.depth_limit(p3)                       # |y| allowed at the seed's x, z
    y0 = np.clip(nodes3d[node, 1], -limit, limit)          # the node's depth, kept inside Ω
    edge = np.where(dark, limit, -limit)                   # y grows away from the camera: back
    t = np.random.default_rng(seed).uniform(0.3, 0.9, len(points))
    p3[:, 1] = y0 + t * (edge - y0)
    return LeafSeeds(points.astype(np.float32), intensity, dark, node.astype(np.int32), p3.astype(np.float32))
