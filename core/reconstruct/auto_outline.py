"""Automatic outline: the tree is what sways while the background stays put.

Harris corners of the whole first frame are tracked (forward–backward LK) over the first
seconds; the camera's own motion is removed by a RANSAC affine fitted to all tracks (most of the
frame is static); corners whose residual motion clearly exceeds the tracker noise are "moving".
Their frame-1 positions are grown into a region (closing, connected components, holes filled),
whose contour is the outline polygon: of the largest component (:func:`auto_outline`), or of every
component at least :data:`TREE_SHARE` of its area, one tree each (:func:`auto_outlines`: trees that
stand apart are never joined into one skeleton). No bpy.
"""
from __future__ import annotations

import cv2
import numpy as np

from ..errors import InputError
from ..outline import Outline, polygon_to_mask, separate_regions
from ..progress import ProgressFn, report
from .tracks import apply_affine, lk_forward_backward
from .video import VideoInfo, iter_frames

#: a swaying region is a tree of its own when at least this share of the largest one's area (a bush
#: or a few leaves of a tree at the frame's edge are less)
TREE_SHARE = 0.25
#: the outlines found, per (video, size, start): the batch counts them before the run that uses them
_FOUND: dict[tuple, list[Outline]] = {}


def auto_outline(info: VideoInfo, start: int = 0, seconds: float = 10.0, max_corners: int = 4000,
                 progress: ProgressFn | None = None) -> Outline:
    """Outline of the swaying tree (the largest swaying region) from frames ``start`` ..
    ``start + seconds·fps`` (px of the scaled video). Raises :class:`InputError` when nothing in
    the clip moves."""
    return max(auto_outlines(info, start, seconds, max_corners, progress), key=lambda o: int(o.mask.sum()))


def auto_outlines(info: VideoInfo, start: int = 0, seconds: float = 10.0, max_corners: int = 4000,
                  progress: ProgressFn | None = None) -> list[Outline]:
    """One outline per swaying region at least :data:`TREE_SHARE` of the largest one's area, left
    to right (see :func:`auto_outline`); found once per video, size and start."""
    key = (info.path, info.width, info.height, start, seconds, max_corners)
    if key not in _FOUND:
        _FOUND.clear()                              # one clip at a time: the last one's outlines
        _FOUND[key] = _find(info, start, seconds, max_corners, progress)
    return list(_FOUND[key])


def _find(info: VideoInfo, start: int, seconds: float, max_corners: int,
          progress: ProgressFn | None) -> list[Outline]:
    n = max(int(round(seconds * info.fps)), 8)
    frames = iter_frames(info, start, min(start + n, info.frame_count))
    first = next(frames, None)
    if first is None:
        raise InputError(f"video '{info.path}' has no frame {start}; check the frame range")
    prev = cv2.cvtColor(first, cv2.COLOR_BGR2GRAY)
    h, w = prev.shape
    pts = cv2.goodFeaturesToTrack(prev, maxCorners=max_corners, qualityLevel=0.001, minDistance=4,
                                  blockSize=3, useHarrisDetector=True, k=0.04)
    if pts is None or len(pts) < 30:
        raise InputError("too few corners in the first frame to find the tree; draw the outline instead")
    p0 = pts.reshape(-1, 2).astype(np.float32)
    cur = p0.copy()
    alive = np.ones(len(p0), bool)
    resid = np.zeros(len(p0))
    steps = 0
    for k, frame in enumerate(frames, start=1):
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        new, ok = lk_forward_backward(prev, gray, cur, 1.0)
        alive &= ok
        cur = np.where(alive[:, None], new, cur).astype(np.float32)
        if alive.sum() >= 10:
            m, _ = cv2.estimateAffinePartial2D(cur[alive], p0[alive], method=cv2.RANSAC,
                                               ransacReprojThreshold=1.0)
            if m is not None:                       # camera motion removed: residual vs frame 1
                d = np.linalg.norm(apply_affine(m, cur) - p0, axis=1)
                resid = np.where(alive, np.maximum(resid, d), resid)
        prev = gray
        steps += 1
        report(progress, "outline", k / n)
    if steps < 4:
        raise InputError("the clip is too short to see the tree move; draw the outline instead")
    noise = max(float(np.percentile(resid, 20)), 0.05)   # the static background (ground, houses)
    # swaying, not travelling: a passer-by's corners move far more than any branch sways
    moving = (resid > max(3.0 * noise, 0.25)) & (resid < 0.1 * max(h, w))
    if moving.sum() < 20:
        raise InputError("nothing in the first seconds moves enough to find the tree "
                         f"({int(moving.sum())} moving corners); draw the outline instead")
    pts_m = p0[moving]
    # grow the moving corners into a region: disks of the typical spacing, closed, largest blob
    from scipy.spatial import cKDTree
    spacing = float(np.median(cKDTree(pts_m).query(pts_m, k=min(6, len(pts_m)))[0][:, -1]))
    r = int(np.clip(1.5 * spacing, 4, 0.06 * max(h, w)))
    mask = np.zeros((h, w), np.uint8)
    for x, y in np.round(pts_m).astype(int):
        cv2.circle(mask, (x, y), r, 255, -1)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
    regions = separate_regions(mask > 0, TREE_SHARE)
    if not regions:
        raise InputError("could not find the tree's region; draw the outline instead")
    out = []
    for region in regions:
        contours, _ = cv2.findContours(region.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        contour = max(contours, key=cv2.contourArea)
        poly = cv2.approxPolyDP(contour, 0.005 * cv2.arcLength(contour, True), True).reshape(-1, 2).astype(np.float32)
        out.append(Outline(poly, polygon_to_mask(poly, w, h)))
    return out
