"""Stage 1 — video reading: stream frames, never the whole clip in memory.

Frames come out as ``(H, W, 3)`` uint8 BGR arrays (OpenCV order), optionally downscaled by
``scale`` (0 < scale <= 1). Frame indices are 0-based; a range is ``[start, stop)``.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Callable, Generator, Iterator

import cv2
import numpy as np

from ..errors import InputError

# FFmpeg prints its own complaints ("moov atom not found") straight to stderr; the user gets our
# one-line error naming the fix instead. An explicit setting by the user wins.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")


@dataclass(frozen=True)
class VideoInfo:
    """What a video file holds. ``width``/``height`` in pixels after ``scale``; ``fps`` frames/s."""

    path: str
    width: int
    height: int
    fps: float
    frame_count: int
    scale: float = 1.0


def parse_frame_range(text: str | None, frame_count: int) -> tuple[int, int]:
    """``"A:B"`` (0-based, B exclusive, either side may be empty) -> ``(start, stop)`` clipped."""
    if text is None or text.strip() in ("", ":"):
        return 0, frame_count
    parts = text.split(":")
    if len(parts) != 2:
        raise InputError(f"frame range '{text}' is not A:B; write e.g. --frames 0:120")
    try:
        start = int(parts[0]) if parts[0].strip() else 0
        stop = int(parts[1]) if parts[1].strip() else frame_count
    except ValueError:
        raise InputError(f"frame range '{text}' is not two integers A:B; write e.g. --frames 0:120") from None
    stop = min(stop, frame_count)
    if start < 0 or stop - start < 2:
        raise InputError(
            f"frame range '{text}' leaves {max(stop - start, 0)} frame(s) of {frame_count}; "
            "give at least 2 frames, e.g. --frames 0:120")
    return start, stop


def open_video(path: str | os.PathLike, scale: float = 1.0) -> VideoInfo:
    """Probe ``path``; raise :class:`InputError` for a missing, unreadable or empty file."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise InputError(f"video '{path}' does not exist; check the path")
    if os.path.isdir(path):
        raise InputError(f"video '{path}' is a folder; give a video file (mp4, mov, avi)")
    if not 0.0 < scale <= 1.0:
        raise InputError(f"scale {scale} is out of range; use a value in (0, 1]")
    cap = cv2.VideoCapture(path)
    try:
        ok, frame = cap.read() if cap.isOpened() else (False, None)
        if not ok or frame is None:
            raise InputError(
                f"video '{path}' cannot be read (unsupported codec or not a video, or it has no frames); "
                "convert it to H.264/MP4, e.g. ffmpeg -i IN -c:v libx264 OUT.mp4")
        fps = float(cap.get(cv2.CAP_PROP_FPS)) or 0.0
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()
    if not np.isfinite(fps) or fps <= 0 or fps > 1000:
        fps = 24.0
    if count <= 0:
        count = sum(1 for _ in _raw_frames(path))
    h, w = frame.shape[:2]
    return VideoInfo(path, int(round(w * scale)), int(round(h * scale)), fps, count, scale)


def _raw_frames(path: str) -> Iterator[np.ndarray]:
    cap = cv2.VideoCapture(path)
    try:
        while True:
            ok, frame = cap.read()
            if not ok:
                return
            yield frame
    finally:
        cap.release()


def iter_frames(info: VideoInfo, start: int = 0, stop: int | None = None,
                times: list | None = None) -> Generator[np.ndarray, None, None]:
    """Yield BGR frames ``start..stop-1`` (``(H, W, 3)`` uint8, scaled), one at a time; with
    ``times`` a list, append each frame's timestamp (seconds, the container's presentation time
    as the decoder reports it) as it is read."""
    stop = info.frame_count if stop is None else stop
    cap = cv2.VideoCapture(info.path)
    try:
        if start > 0:
            cap.set(cv2.CAP_PROP_POS_FRAMES, start)
        for _ in range(start, stop):
            ok, frame = cap.read()
            if not ok:
                return
            if times is not None:
                times.append(cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0)
            if info.scale != 1.0:
                frame = cv2.resize(frame, (info.width, info.height), interpolation=cv2.INTER_AREA)
            yield frame
    finally:
        cap.release()


def frame_times(stamps, fps: float) -> tuple[np.ndarray, float, str | None]:
    """Frame times ``(F,)`` seconds from the first frame, from the decoder's ``stamps`` where they
    are usable (finite, strictly increasing), else ``index / fps``; also the clip's frame rate
    (frames over the time they span: what the header's ``fps`` should have said) and a warning
    when it differs from the header by more than 2 %, or when the frames are irregular."""
    st = np.asarray(stamps, np.float64)
    n = len(st)
    even = np.arange(n) / fps
    if n < 2 or not np.isfinite(st).all() or (np.diff(st) <= 0).any():
        return even, fps, None
    t = st - st[0]
    rate = (n - 1) / t[-1]
    dt = np.diff(t)
    notes = []
    if abs(rate - fps) > 0.02 * fps:
        notes.append(f"the video's header says {fps:g} fps but its {n} frames span {t[-1]:.2f} s "
                     f"({rate:.3g} fps); times and sway frequencies use the frames' timestamps")
    if dt.std() > 0.1 * dt.mean():
        notes.append(f"the frame rate varies (frame gaps {dt.min() * 1000:.0f}-{dt.max() * 1000:.0f} ms); "
                     "times use the frames' timestamps, keys are spaced at the mean rate")
    return t, float(rate), "; ".join(notes) or None


def prefetch(frames: Iterator[Any], depth: int = 4, transform: Callable[[Any], Any] | None = None) -> Iterator[Any]:
    """Decode ahead in a background thread (OpenCV releases the GIL), keeping ``depth`` frames;
    with ``transform``, yield ``transform(frame)`` computed in that thread too (work on a frame
    that needs nothing from the frames before it: the second core prepares while the first tracks).

    Errors in the reader are re-raised in the consumer; closing the generator stops the reader.
    """
    import queue
    import threading

    q: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()
    done = object()

    def reader():
        try:
            for f in frames:
                if transform is not None:
                    f = transform(f)
                while not stop.is_set():
                    try:
                        q.put(f, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if stop.is_set():
                    return
            q.put(done)
        except BaseException as exc:  # hand it to the consumer
            q.put(exc)

    th = threading.Thread(target=reader, name="tree_from_video-decode", daemon=True)
    th.start()
    try:
        while True:
            item = q.get()
            if item is done:
                return
            if isinstance(item, BaseException):
                raise item
            yield item
    finally:
        stop.set()
        th.join(timeout=5)
