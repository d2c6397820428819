"""The trunk's own pixels in frame 1 as a photo of its bark (issue 36 part 1, ``--bark-image video``).

The trace's trunk (root to the first fork, :func:`..topology.trunk_chain`) is straightened: the
frame is sampled along the chain every pixel of arc length and across it out to :data:`CORE` of
the trunk's measured radius each way (the middle of the trunk: its lit face, not its silhouette's
edge against the sky), so the strip's rows run up the trunk and its columns across it. A strip
shorter than :data:`MIN_ROWS` px or under :data:`MIN_TREE` tree pixels (frame 1's tree map) is no
bark photo (None: the run says so and keeps the procedural bark). The strip is scaled up so its
shorter side is :data:`.bark_photo.MIN_PHOTO_PX` (the quilting's patches need that many): a
low-resolution bark, but the trunk's own colours and furrows.
"""
from __future__ import annotations

import cv2
import numpy as np

from ..topology import trunk_chain
from .bark_photo import MIN_PHOTO_PX

#: the ``--bark-image`` that means this
VIDEO_BARK = "video"
#: across the trunk, the strip reaches this share of its radius each way
CORE = 0.7
#: a strip needs this many rows (px of trunk) and this share of tree pixels
MIN_ROWS = 16
MIN_TREE = 0.8
#: a strip narrower than this many px is widened to it (a thin trunk's centre line)
MIN_HALF_PX = 2


def trunk_strip(frame: np.ndarray, parents: np.ndarray, nodes2d: np.ndarray, radius_px: np.ndarray,
                tree_px: np.ndarray | None = None) -> tuple[np.ndarray | None, str]:
    """``(strip (R, C, 3) BGR uint8 or None, why)``: frame 1's trunk straightened (module docstring),
    from the skeleton ``parents``, ``nodes2d (N, 2)`` px and ``radius_px (N,)``."""
    chain = trunk_chain(np.asarray(parents))
    pts = np.asarray(nodes2d, np.float64)[chain]
    if len(pts) < 2:
        return None, "the trace has no trunk"
    seg = np.diff(pts, axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])
    length = float(s[-1])
    if length < MIN_ROWS:
        return None, f"the trunk is {length:.0f} px long in frame 1 (under {MIN_ROWS})"
    r = np.asarray(radius_px, np.float64)[chain]
    half = max(int(round(CORE * float(np.nanmedian(r)))), MIN_HALF_PX) if np.isfinite(r).any() else MIN_HALF_PX
    t = np.arange(0.0, length, 1.0)[::-1]                      # rows from the trunk's top down to its base
    cx, cy = np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])
    k = np.clip(np.searchsorted(s, t, side="right") - 1, 0, len(seg) - 1)
    d = seg[k] / np.maximum(np.hypot(seg[k, 0], seg[k, 1]), 1e-9)[:, None]
    across = np.stack([-d[:, 1], d[:, 0]], 1)                     # perpendicular, to the trunk's right
    u = np.arange(-half, half + 1, dtype=np.float64)
    mx = (cx[:, None] + u[None] * across[:, :1]).astype(np.float32)
    my = (cy[:, None] + u[None] * across[:, 1:]).astype(np.float32)
    strip = cv2.remap(frame, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    if tree_px is not None:
        on = cv2.remap(tree_px.astype(np.uint8), mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT)
        share = float(on.mean())
        if share < MIN_TREE:
            return None, f"only {share:.0%} of the trunk's strip is the tree in frame 1 (under {MIN_TREE:.0%})"
    f = MIN_PHOTO_PX / min(strip.shape[:2])
    if f > 1:
        strip = cv2.resize(strip, (int(round(strip.shape[1] * f)), int(round(strip.shape[0] * f))),
                           interpolation=cv2.INTER_CUBIC)
    return strip, f"a strip {2 * half + 1}×{int(length)} px of the trunk in frame 1"
