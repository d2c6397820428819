"""Drawing tracks and the skeleton over the video (``overlay.png`` for frame 1, ``overlay.mp4``)."""
from __future__ import annotations

import errno
import os
import tempfile

import cv2
import numpy as np

from ..fileio import atomic_write_bytes, publish
from ..progress import ProgressFn, report
from .node_motion import LOW_CONFIDENCE
from .skeleton2d import Skeleton2D
from .tracks import Tracks
from .video import VideoInfo, iter_frames

#: BGR of a node's motion confidence: below LOW_CONFIDENCE (poorly measured), up to 0.78 (≈ 3 tracks), above
CONFIDENCE_COLOURS = ((40, 40, 255), (0, 220, 255), (80, 230, 80))
LEVEL_COLOURS = [(40, 40, 255), (0, 160, 255), (0, 230, 255), (80, 255, 120), (255, 200, 0),
                 (255, 80, 200), (200, 200, 200)]


def to_image(points: np.ndarray, cam: np.ndarray) -> np.ndarray:
    """Frame-1 coordinates ``(..., 2)`` → this frame's image, given its image→frame-1 ``cam (2, 3)``."""
    inv = cv2.invertAffineTransform(np.asarray(cam, np.float64))
    return points @ inv[:, :2].T + inv[:, 2]


def confidence_bins(confidence: np.ndarray) -> np.ndarray:
    """Index into :data:`CONFIDENCE_COLOURS` for each confidence: 0 below ``LOW_CONFIDENCE``, 1 up to
    0.78, 2 above."""
    c = np.asarray(confidence)
    return np.where(c < LOW_CONFIDENCE, 0, np.where(c < 0.78, 1, 2))


#: BGR of frame 1's foreground outline (the tree's pixels the look is judged against)
FOREGROUND_COLOUR = (255, 255, 0)


def draw_frame(img: np.ndarray, skel: Skeleton2D, tracks: Tracks, t: int, zoom: int = 1,
               foreground: np.ndarray | None = None) -> np.ndarray:
    """Draw valid tracks (small green dots) and the skeleton at frame ``t`` on a copy of ``img``,
    enlarged ``zoom`` times (small videos stay readable). Edges are coloured by branching level;
    branch points and tips are marked; every node gets a dot coloured by its motion confidence in
    that frame (red: poorly measured, yellow, green). In frame 1 (``t == 0``) with ``foreground
    (H, W)`` bool (:mod:`.foreground`), its outline in cyan: the tree's pixels the leaves fill."""
    out = cv2.resize(img, None, fx=zoom, fy=zoom, interpolation=cv2.INTER_LINEAR) if zoom > 1 else img.copy()
    if t == 0 and foreground is not None:
        fg = cv2.resize(foreground.astype(np.uint8), (out.shape[1], out.shape[0]), interpolation=cv2.INTER_NEAREST)
        contours, _ = cv2.findContours(fg, cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(out, contours, -1, FOREGROUND_COLOUR, 1, cv2.LINE_AA)
    cam = tracks.camera[t]
    pts = to_image(tracks.points[t][tracks.valid[t]], cam) * zoom
    for x, y in np.round(pts).astype(int):
        cv2.circle(out, (x, y), 1, (60, 255, 60), -1)
    nodes = to_image(skel.nodes2d[t].astype(np.float64), cam) * zoom
    thick = max(2, int(round(out.shape[0] / 360)))
    fixed = np.round(nodes * 16).astype(int)
    for p, c in skel.edges():
        col = LEVEL_COLOURS[min(int(skel.level[c]), len(LEVEL_COLOURS) - 1)]
        cv2.line(out, tuple(fixed[p]), tuple(fixed[c]), (20, 20, 20), thick + 2, cv2.LINE_AA, shift=4)
        cv2.line(out, tuple(fixed[p]), tuple(fixed[c]), col, thick, cv2.LINE_AA, shift=4)
    n_kids = np.bincount(skel.parents[skel.parents >= 0], minlength=skel.n_nodes)
    for i in np.flatnonzero(n_kids != 1):
        cv2.circle(out, tuple(fixed[i]), (thick + 1) * 16, (255, 255, 255), -1, cv2.LINE_AA, shift=4)
    if skel.confidence is not None:
        bins = confidence_bins(skel.confidence[t])
        for i in range(skel.n_nodes):
            cv2.circle(out, tuple(fixed[i]), thick * 16, CONFIDENCE_COLOURS[bins[i]], -1, cv2.LINE_AA, shift=4)
    return out


def overlay_zoom(height: int) -> int:
    """Enlargement for overlays: small videos (e.g. 360 px) are drawn 2× so lines stay readable."""
    return int(min(3, max(1, round(720 / max(height, 1)))))


def _check_written(tmp: str, n: int, path: str) -> None:
    """OpenCV's video writer fails silently (a full disk leaves a short file): an ``OSError`` unless
    ``tmp`` holds ``n`` frames."""
    cap = cv2.VideoCapture(tmp)
    frames = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if cap.isOpened() else 0
    cap.release()
    if frames < n:
        st = os.statvfs(os.path.dirname(os.path.abspath(tmp)))
        full = st.f_bavail * st.f_frsize < 1 << 20
        raise OSError(errno.ENOSPC if full else errno.EIO,
                      os.strerror(errno.ENOSPC) if full else f"the video writer wrote {frames} of {n} frames", path)


def write_overlays(info: VideoInfo, start: int, skel: Skeleton2D, tracks: Tracks, png_path: str,
                   mp4_path: str | None, progress: ProgressFn | None = None,
                   foreground: np.ndarray | None = None) -> None:
    """Write ``png_path`` (frame 1) and, if given, ``mp4_path`` (every frame), atomically; frame 1
    with the outline of its ``foreground`` (H, W) bool when given."""
    n = tracks.n_frames
    zoom = overlay_zoom(info.height)
    writer = tmp = None
    try:
        for t, frame in enumerate(iter_frames(info, start, start + n)):
            img = draw_frame(frame, skel, tracks, t, zoom, foreground)
            if t == 0:
                ok, png = cv2.imencode(".png", img)
                if not ok:
                    raise RuntimeError("OpenCV could not encode the overlay as PNG")
                atomic_write_bytes(png_path, png.tobytes())          # a full disk raises here, nothing published
                if mp4_path is None:
                    return
                fd, tmp = tempfile.mkstemp(suffix=".mp4", dir=os.path.dirname(os.path.abspath(mp4_path)))
                os.close(fd)
                writer = cv2.VideoWriter(tmp, cv2.VideoWriter_fourcc(*"mp4v"), info.fps,
                                         (img.shape[1], img.shape[0]))
            assert writer is not None
            writer.write(img)
            if t % 10 == 0:
                report(progress, "overlay", t / n)
        assert writer is not None and tmp is not None and mp4_path is not None
        writer.release()
        writer = None
        _check_written(tmp, n, mp4_path)
        publish(tmp, mp4_path)
        tmp = None
    finally:
        if writer is not None:
            writer.release()
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
