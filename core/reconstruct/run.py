"""The 2D stages strung together: one streaming pass over the video (tracks + bark statistics)
→ hierarchy → moving 2D skeleton (paper §2 and Appendix A, or the traced skeleton).

:func:`run` takes a video and an outline and returns a :class:`Result`; the 3D lift and motion
(:mod:`.lift`, :mod:`.motion`) and the details are strung on top of it by
:func:`tree_from_video.core.pipeline.build_3d`.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import cv2
import numpy as np

from ..errors import InputError
from ..forms import FORMS
from ..outline import Outline, load_outlines, polygon_outline
from ..params import check, param
from ..progress import ProgressFn, expected_seconds, report, stage_split, sub_progress
from . import cache
from .appearance import AppearanceAccumulator, AppearanceMaps
from .foreground import Foreground, foreground
from .form import detect_form, found_outline_note, palm_hint
from .hierarchy import Hierarchy, HierarchyParams, build_hierarchy
from .node_motion import confidence_warning
from .skeleton2d import FOLD_ALPHA, Skeleton2D, paper_skeleton
from .trace import TraceParams, traced_skeleton
from .tracks import Tracker, TrackParams, Tracks
from .video import VideoInfo, frame_times, iter_frames, open_video, parse_frame_range, prefetch

SKELETON_KINDS = ("traced", "paper")

#: Seconds a 2D stage takes ≈ fixed + per frame × frames ``(fixed s, s per frame)``, measured on
#: sample_videos/broad and sparse (480×360 px, 12 to 180 frames, no cache; the bpy 5.0.1 wheel and
#: Blender 4.3 on 2 cores, each stage timed alone): tracking with the dense flow from frame 1
#: 0.19–0.21 s at 24 frames, 0.35–0.38 s at 48 and 1.32–1.35 s at 180 (broad; sparse 1.0 s), i.e.
#: ≈ 7 ms a frame (5.5 before the flow); the hierarchy 0.03–0.36 s whatever the length; the traced
#: skeleton 0.10–0.32 s at 12–48 frames and 0.45–0.98 s at 180. The progress bar gives each stage
#: its share of the expected total (with the 3D stages of :data:`..pipeline.STAGE_COSTS_3D`), so it
#: moves at an even pace; before, tracking had 70 % of the 2D bar and the motion 20 % of the whole.
#: Frame 1's foreground (read again, colour tests and the graph cut at ≤ 640 px, 0.35–0.6 s at
#: 480×360 whatever the length) is cut in a thread while the video is tracked: it lengthens the
#: tracking by ~0.2 s (48 frames of broad: tracking ends at 0.47 of the run, the bar said 0.22) and
#: is ready when the tracking ends.
STAGE_COSTS_2D = {"tracking": (0.25, 0.007), "hierarchy": (0.12, 0.0), "foreground": (0.02, 0.0),
                  "skeleton": (0.15, 0.002)}


@dataclass
class ReconstructSettings:
    """What the 2D stages need besides the input files (defaults: the product's)."""

    levels: int = param(6, 2, 9, what="levels", fix="the paper uses 5–7")
    skeleton: str = param("traced", choices=SKELETON_KINDS, what="skeleton")
    form: str = param("auto", choices=FORMS, what="tree form")   # auto: detected from the outline
    fold_alpha: float = param(FOLD_ALPHA, 0.0, 1.0, what="fold α")   # paper skeleton: x'_i += α (x'_j − x'_i)
    frames: str | None = None       # "A:B", 0-based, B exclusive
    scale: float = param(1.0, 0.0, 1.0, lo_open=True, what="scale")   # downscale factor for the video
    cache_dir: str | None = None    # keep tracks + hierarchy here, keyed by video and settings
    track: TrackParams = field(default_factory=TrackParams)
    trace: TraceParams = field(default_factory=TraceParams)


@dataclass
class Result:
    """The 2D reconstruction: the video read, the outline, the frame range ``start..stop-1``, the
    tracks, the motion hierarchy, the appearance maps, the moving 2D skeleton, frame 1's
    foreground and the tree's form."""

    info: VideoInfo
    outline: Outline
    start: int
    stop: int
    tracks: Tracks
    hierarchy: Hierarchy
    maps: AppearanceMaps
    skeleton: Skeleton2D
    foreground: Foreground | None = None      # frame 1's tree pixels (None: frame 1 unreadable)
    form: str = "broadleaf"                   # the tree's form (..forms.TREE_FORMS), given or detected
    form_why: str = ""                        # how it was decided

    @property
    def warnings(self) -> list[str]:
        return list(dict.fromkeys(self.tracks.warnings + self.skeleton.warnings))


def check_reconstruct(s: ReconstructSettings) -> None:
    """Raise :class:`InputError` for a 2D setting out of range."""
    check(s)


def track_video(info: VideoInfo, outline: Outline, start: int, stop: int, params: TrackParams,
                progress: ProgressFn | None = None) -> tuple[Tracks, AppearanceMaps]:
    """One pass over frames ``start..stop-1``: tracks and appearance maps together."""
    return track_videos(info, [outline], start, stop, params, progress)[0]


def track_videos(info: VideoInfo, outlines: list[Outline], start: int, stop: int, params: TrackParams,
                 progress: ProgressFn | None = None) -> list[tuple[Tracks, AppearanceMaps]]:
    """One pass over frames ``start..stop-1`` for every tree of ``outlines``: each frame is decoded
    once and fed to one tracker and one appearance accumulator per outline (the camera measured
    on the background outside all of them)."""
    stamps: list[float] = []
    decoded = iter_frames(info, start, stop, stamps)
    first = next(decoded, None)
    if first is None:
        raise InputError(f"video '{info.path}' has no frame {start}; check --frames")
    trees = np.logical_or.reduce([o.mask for o in outlines]) if len(outlines) > 1 else None
    trackers = [Tracker(first, o, info.fps, start, params, trees) for o in outlines]
    for k, tracker in enumerate(trackers):
        if len(tracker.raw) < 8:
            decoded.close()
            which = f"outline {k + 1} of {len(outlines)}" if len(outlines) > 1 else "the outline"
            raise InputError(f"only {len(tracker.raw)} trackable corners inside {which}; "
                             "outline the whole tree (leaves and trunk) in the first frame")
    accs = [AppearanceAccumulator(first, o) for o in outlines]

    prepared = [0]

    def prepare(frame: np.ndarray):
        """In the decoding thread: each tracker's images, the appearance's small grey and, when
        due, the dense flow from frame 1 (at the frame's timestamp: the reader has appended it)."""
        prepared[0] += 1
        t = stamps[-1] - stamps[0] if len(stamps) > prepared[0] else np.nan
        t = t if np.isfinite(t) and t > 0 else prepared[0] / max(info.fps, 1e-3)
        out = []
        for tracker, acc in zip(trackers, accs):
            images = tracker.prepare(frame)
            out.append((images, acc.shrink(images[0]), tracker.flow.compute(images[1], float(t))))
        return out

    total = stop - start
    for k, per_tree in enumerate(prefetch(decoded, transform=prepare), start=1):
        # the reader appends each frame's timestamp before handing it over; dt in units of the
        # clip's typical interval (median of the last 50), whatever its header says
        gaps = np.diff(stamps[max(0, k - 50):k + 1]) if len(stamps) > k else np.ones(1)
        dt = gaps[-1] / np.median(gaps) if np.median(gaps) > 0 else 1.0
        for tracker, acc, (images, small, flow) in zip(trackers, accs, per_tree):
            tracker.flow.add(k, flow)
            tracker.feed(None, dt if np.isfinite(dt) and dt > 0 else 1.0, images)
            acc.feed(None, tracker.camera[-1], small)
        if k % 5 == 0:
            report(progress, "tracking", k / total)
    out = []
    for tracker, acc in zip(trackers, accs):
        tracks = tracker.result()
        tracks.times, tracks.fps, note = frame_times(stamps[:tracks.n_frames], info.fps)
        if note:
            tracks.warnings.append(note)
        out.append((tracks, acc.maps()))
    return out


def read_outlines(info: VideoInfo, start: int, outline_path, scale: float,
                  photo: np.ndarray | None = None) -> list[Outline]:
    """The trees' outlines of ``outline_path`` (see :func:`run_all`) for the video ``info``
    (``photo``: its frame ``start`` when the caller has already read it, BGR uint8)."""
    if isinstance(outline_path, str) and outline_path == "auto":   # every tree that stands apart
        if info.frame_count - start <= 1:                          # a photo: nothing sways to find it by
            from .photo_outline import photo_outline
            frame = photo if photo is not None else next(iter_frames(info, start, start + 1))
            return [photo_outline(frame, f"'{os.path.basename(info.path)}'")]
        from .auto_outline import auto_outlines
        return auto_outlines(info, start)
    if isinstance(outline_path, (str, os.PathLike)):
        return load_outlines(outline_path, info.width, info.height, scale)
    several = isinstance(outline_path, (list, tuple)) and len(outline_path) > 0 \
        and all(np.ndim(p) == 2 for p in outline_path)             # a list of polygons, not of points
    arr = list(outline_path) if several else [outline_path]
    return [polygon_outline(np.asarray(p, float) * scale, info.width, info.height,
                            "the outline" if len(arr) == 1 else f"outline {k + 1}") for k, p in enumerate(arr)]


def count_outlines(video: str, outline_path, scale: float = 1.0, frames: str | None = None) -> int:
    """How many trees ``outline_path`` outlines in the clip's range ``frames`` ("A:B"), read before
    the work (the batch checks each tree's output folder first; ``"auto"`` finds its outlines
    once, and :func:`run_all` takes them from there). Raises InputError as :func:`run_all`."""
    info = open_video(video, scale)
    start, _ = parse_frame_range(frames, info.frame_count)
    return len(read_outlines(info, start, outline_path, scale))


def run(video: str, outline_path, settings: ReconstructSettings | None = None,
        progress: ProgressFn | None = None) -> Result:
    """Video + outline → tracks, hierarchy and moving 2D skeleton of one tree (:func:`run_all`,
    whose outline must hold one tree). Raises InputError on bad input."""
    results = run_all(video, outline_path, settings, progress, one=True)
    return results[0]


def run_all(video: str, outline_path, settings: ReconstructSettings | None = None,
            progress: ProgressFn | None = None, one: bool = False) -> list[Result]:
    """Video + outlines → one :class:`Result` per tree, from one decode and one tracking pass.
    Raises InputError on bad input (with ``one``, also for an outline of several trees).

    ``outline_path``: a polygon .json (one polygon, or a list of them: one tree each) or mask image
    path (each large component a tree), ``"auto"`` (what sways in the first seconds,
    :mod:`.auto_outline`; in a photo, a one-frame video, the tree :mod:`.photo_outline` finds, whose
    outlines must each hold a tree's texture), a polygon ``(M, 2)`` array in pixels of the original video (e.g. from a
    Blender Mask) or a list of them."""
    s = settings or ReconstructSettings()
    check_reconstruct(s)
    info = open_video(video, s.scale)
    start, stop = parse_frame_range(s.frames, info.frame_count)
    # a photo is decoded once: its outline may be found on it, each outline must hold a tree, and
    # it is frame 1 of the work below
    photo = frame_one(info, start, (info.height, info.width)) if info.frame_count - start <= 1 else None
    outlines = read_outlines(info, start, outline_path, s.scale, photo)
    if photo is not None:                            # a photo: each outline must hold a tree
        from .photo_outline import check_tree_inside
        for k, o in enumerate(outlines):
            check_tree_inside(photo, o.mask, f"'{os.path.basename(info.path)}'" if len(outlines) == 1
                              else f"outline {k + 1} of '{os.path.basename(info.path)}'")
    if one and len(outlines) > 1:
        raise InputError(f"the outline holds {len(outlines)} trees; reconstruct one at a time, or all of "
                         "them with the batch (one folder per tree)")
    n = len(outlines)
    costs = expected_seconds(STAGE_COSTS_2D, stop - start)
    parts = stage_split(progress, {k: v * (n if k != "tracking" else 1) for k, v in costs.items()})
    cached = key = None
    if s.cache_dir and n == 1:
        key = cache.stage_key(video, outlines[0].mask, start, stop, s.scale, s.track, s.levels)
        cached = cache.load(s.cache_dir, key)
    frame = photo if photo is not None else frame_one(info, start, outlines[0].mask.shape)
    # frame 1's foreground needs nothing from tracking: it is cut in a thread while the video is
    # tracked (OpenCV releases the GIL), so its single-core graph cut shares the tracking's two
    # cores instead of running alone after them (1080p dense crown: 2.1 s of a 16 s run)
    early = _frame_one_work(frame, outlines, s.form,
                            photo is not None and isinstance(outline_path, str) and outline_path == "auto")
    if cached is not None:
        per_tree = [cached[:2]]
        hiers = [cached[2]]
        report(parts["hierarchy"], "tracking (cached)", 1.0)
    else:
        per_tree = track_videos(info, outlines, start, stop, s.track, parts["tracking"])
        hiers = [build_hierarchy(t, HierarchyParams(levels=s.levels), sub_progress(parts["hierarchy"], k / n, (k + 1) / n))
                 for k, (t, _) in enumerate(per_tree)]
        if key is not None and s.cache_dir:
            try:
                cache.save(s.cache_dir, key, per_tree[0][0], per_tree[0][1], hiers[0])
            except OSError:
                pass                # a cache that cannot be written only costs time
    results = []
    for k, (outline, (tracks, maps), hier, job) in enumerate(zip(outlines, per_tree, hiers, early)):
        sub = {st: sub_progress(parts[st], k / n, (k + 1) / n) for st in ("foreground", "skeleton")}
        report(sub["foreground"], "foreground", 0.0)
        look = job.result()
        report(sub["foreground"], "foreground", 1.0)
        results.append(_one_tree(info, outline, start, stop, tracks, maps, hier, look, s, sub))
    return results


@dataclass
class FrameOne:
    """What frame 1 alone gives one tree: its foreground (None without a frame), the form (chosen,
    or detected from the outline) with why, and its warnings: the suggestion to choose Palm, and
    what a form read from an outline found on a photo is worth (each None when it does not apply)."""
    fg: Foreground | None
    form: str
    why: str
    hint: str | None
    note: str | None = None


def _frame_one_look(frame: np.ndarray | None, outline: Outline, form: str, found_on_photo: bool = False) -> FrameOne:
    """Frame 1's foreground, the form and the warnings of one tree (``found_on_photo``: its
    outline was found on a photo, where the form its shape gives is unreliable)."""
    fg = foreground(frame, outline.mask) if frame is not None else None
    if form != "auto":
        return FrameOne(fg, form, "chosen", None)
    form, why = detect_form(outline.mask)
    hint = palm_hint(frame, None if fg is None else fg.mask) if form == "broadleaf" else None
    return FrameOne(fg, form, why, hint, found_outline_note(form, why) if found_on_photo else None)


def _frame_one_work(frame: np.ndarray | None, outlines: list[Outline], form: str, found_on_photo: bool = False) -> list:
    """:func:`_frame_one_look` of every outline, started in one worker thread: futures, in order
    (an error is raised by the future's ``result()``)."""
    from concurrent.futures import ThreadPoolExecutor
    pool = ThreadPoolExecutor(1, thread_name_prefix="tree_from_video-frame1")
    jobs = [pool.submit(_frame_one_look, frame, o, form, found_on_photo) for o in outlines]
    pool.shutdown(wait=False)       # the queued trees still run; the thread then ends
    return jobs


def _one_tree(info: VideoInfo, outline: Outline, start: int, stop: int, tracks: Tracks, maps: AppearanceMaps,
              hier: Hierarchy, look: FrameOne, s: ReconstructSettings, parts: dict) -> Result:
    """The moving 2D skeleton of one tree, given what frame 1 gives (:class:`FrameOne`)."""
    fg, form, why, hint = look.fg, look.form, look.why, look.hint
    sk_prog = parts["skeleton"]
    if s.skeleton == "paper":
        skel = paper_skeleton(tracks, hier, outline, alpha=s.fold_alpha, progress=sk_prog)
    else:
        skel = traced_skeleton(tracks, hier, outline, maps, s.trace, sk_prog, None if fg is None else fg.mask, form)
    note = confidence_warning(skel.confidence) if skel.confidence is not None else None
    for line in (note, hint, look.note):
        if line:
            skel.warnings.append(line)
    return Result(info, outline, start, stop, tracks, hier, maps, skel, fg, form, why)


def frame_one(info: VideoInfo, start: int, shape: tuple[int, ...]) -> np.ndarray | None:
    """Frame ``start`` (BGR uint8) at ``shape`` (H, W) — the outline's, the processing scale's —
    or None when it cannot be read again."""
    frame = next(iter_frames(info, start, start + 1), None)
    if frame is None:
        return None
    if frame.shape[:2] != tuple(shape[:2]):
        frame = cv2.resize(frame, (shape[1], shape[0]), interpolation=cv2.INTER_AREA)
    return frame
