"""The stages run in order on one streaming pass over the video: video → tracks → hierarchy →
skeleton2d. Later stages (lift3d, motion, ...) extend :func:`run`."""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2

from .appearance import AppearanceAccumulator, AppearanceMaps
from .errors import InputError
from .hierarchy import Hierarchy, HierarchyParams, build_hierarchy
from .outline import Outline, load_outline
from .progress import ProgressFn, report, sub_progress
from .skeleton2d import Skeleton2D, paper_skeleton
from .trace import TraceParams, traced_skeleton
from .tracks import Tracker, TrackParams, Tracks
from .video import VideoInfo, iter_frames, open_video, parse_frame_range, prefetch

SKELETON_KINDS = ("traced", "paper")


@dataclass
class Settings:
    """Everything a run needs besides the input files."""

    levels: int = 6
    skeleton: str = "traced"
    frames: str | None = None       # "A:B", 0-based, B exclusive
    scale: float = 1.0              # downscale factor for the video (0 < scale <= 1)
    track: TrackParams = field(default_factory=TrackParams)
    trace: TraceParams = field(default_factory=TraceParams)


@dataclass
class Result:
    info: VideoInfo
    outline: Outline
    start: int
    stop: int
    tracks: Tracks
    hierarchy: Hierarchy
    maps: AppearanceMaps
    skeleton: Skeleton2D

    @property
    def warnings(self) -> list[str]:
        return list(dict.fromkeys(self.tracks.warnings + self.skeleton.warnings))


def check_settings(s: Settings) -> None:
    if s.skeleton not in SKELETON_KINDS:
        raise InputError(f"unknown skeleton '{s.skeleton}'; choose one of {', '.join(SKELETON_KINDS)}")
    if not 2 <= s.levels <= 9:
        raise InputError(f"levels {s.levels} out of range; use 2..9 (the paper uses 5–7)")


def track_video(info: VideoInfo, outline: Outline, start: int, stop: int, params: TrackParams,
                progress: ProgressFn | None = None) -> tuple[Tracks, AppearanceMaps]:
    """One pass over frames ``start..stop-1``: tracks and appearance maps together."""
    frames = prefetch(iter_frames(info, start, stop))
    first = next(frames, None)
    if first is None:
        raise InputError(f"video '{info.path}' has no frame {start}; check --frames")
    tracker = Tracker(first, outline, info.fps, start, params)
    if len(tracker.raw) < 8:
        raise InputError(f"only {len(tracker.raw)} trackable corners inside the outline; "
                         "outline the whole tree (leaves and trunk) in the first frame")
    acc = AppearanceAccumulator(first, outline)
    total = stop - start
    for k, frame in enumerate(frames, start=1):
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        tracker.feed(gray)
        acc.feed(gray, tracker.camera[-1])
        if k % 5 == 0:
            report(progress, "tracking", k / total)
    return tracker.result(), acc.maps()


def run(video: str, outline_path: str, settings: Settings | None = None,
        progress: ProgressFn | None = None) -> Result:
    """Video + outline → tracks, hierarchy and moving 2D skeleton. Raises InputError on bad input."""
    s = settings or Settings()
    check_settings(s)
    info = open_video(video, s.scale)
    start, stop = parse_frame_range(s.frames, info.frame_count)
    outline = load_outline(outline_path, info.width, info.height, s.scale)
    tracks, maps = track_video(info, outline, start, stop, s.track, sub_progress(progress, 0.0, 0.7))
    hier = build_hierarchy(tracks, HierarchyParams(levels=s.levels), sub_progress(progress, 0.7, 0.85))
    sk_prog = sub_progress(progress, 0.85, 1.0)
    if s.skeleton == "paper":
        skel = paper_skeleton(tracks, hier, outline, progress=sk_prog)
    else:
        skel = traced_skeleton(tracks, hier, outline, maps, s.trace, sk_prog)
    return Result(info, outline, start, stop, tracks, hier, maps, skel)
