"""Drawing tracks and the skeleton over the video (``overlay.png`` for frame 1, ``overlay.mp4``)."""
from __future__ import annotations

import os
import tempfile

import cv2
import numpy as np

from .progress import ProgressFn, report
from .skeleton2d import Skeleton2D
from .tracks import Tracks
from .video import VideoInfo, iter_frames

LEVEL_COLOURS = [(40, 40, 255), (0, 160, 255), (0, 230, 255), (80, 255, 120), (255, 200, 0),
                 (255, 80, 200), (200, 200, 200)]


def to_image(points: np.ndarray, cam: np.ndarray) -> np.ndarray:
    """Frame-1 coordinates ``(..., 2)`` → this frame's image, given its image→frame-1 ``cam (2, 3)``."""
    inv = cv2.invertAffineTransform(np.asarray(cam, np.float64))
    return points @ inv[:, :2].T + inv[:, 2]


def draw_frame(img: np.ndarray, skel: Skeleton2D, tracks: Tracks, t: int) -> np.ndarray:
    """Draw valid tracks (small dots) and the skeleton at frame ``t`` on a copy of ``img``."""
    out = img.copy()
    cam = tracks.camera[t]
    pts = to_image(tracks.points[t][tracks.valid[t]], cam)
    for x, y in np.round(pts).astype(int):
        cv2.circle(out, (x, y), 1, (60, 255, 60), -1, cv2.LINE_AA)
    nodes = to_image(skel.nodes2d[t].astype(np.float64), cam)
    thick = max(1, int(round(img.shape[0] / 300)))
    for p, c in skel.edges():
        col = LEVEL_COLOURS[min(int(skel.level[c]), len(LEVEL_COLOURS) - 1)]
        a = tuple(np.round(nodes[p] * 16).astype(int))
        b = tuple(np.round(nodes[c] * 16).astype(int))
        cv2.line(out, a, b, col, thick + 1, cv2.LINE_AA, shift=4)
    for i, (x, y) in enumerate(nodes):
        cv2.circle(out, (int(round(x * 16)), int(round(y * 16))), (thick + 1) * 16, (255, 255, 255), -1,
                   cv2.LINE_AA, shift=4)
    return out


def write_overlays(info: VideoInfo, start: int, skel: Skeleton2D, tracks: Tracks, png_path: str,
                   mp4_path: str | None, progress: ProgressFn | None = None) -> None:
    """Write ``png_path`` (frame 1) and, if given, ``mp4_path`` (every frame), atomically."""
    n = tracks.n_frames
    writer = tmp = None
    try:
        for t, frame in enumerate(iter_frames(info, start, start + n)):
            img = draw_frame(frame, skel, tracks, t)
            if t == 0:
                fd, tmp_png = tempfile.mkstemp(suffix=".png", dir=os.path.dirname(os.path.abspath(png_path)))
                os.close(fd)
                cv2.imwrite(tmp_png, img)
                os.replace(tmp_png, png_path)
                if mp4_path is None:
                    return
                fd, tmp = tempfile.mkstemp(suffix=".mp4", dir=os.path.dirname(os.path.abspath(mp4_path)))
                os.close(fd)
                writer = cv2.VideoWriter(tmp, cv2.VideoWriter_fourcc(*"mp4v"), info.fps,
                                         (img.shape[1], img.shape[0]))
            writer.write(img)
            if t % 10 == 0:
                report(progress, "overlay", t / n)
        writer.release()
        writer = None
        os.replace(tmp, mp4_path)
        tmp = None
    finally:
        if writer is not None:
            writer.release()
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
