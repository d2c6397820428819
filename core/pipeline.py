"""The stages in order: one streaming pass over the video (tracks + bark statistics) →
hierarchy → skeleton2d (:func:`run`), then lift3d → motion → :class:`Tree3D` (:func:`build_3d`)."""
from __future__ import annotations

import os
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from . import cache
from .appearance import AppearanceAccumulator, AppearanceMaps
from .branch_fit import fit_to_video, measure_branches, tree_map
from .errors import InputError
from .hierarchy import Hierarchy, HierarchyParams, build_hierarchy
from .leaves import LeafParams, place_leaves
from .lift3d import LiftParams, envelope_to_meta, lift
from .motion import MotionParams, solve_motion
from .outline import Outline, load_outline, polygon_outline
from .progress import ProgressFn, report, sub_progress
from .skeleton2d import Skeleton2D, paper_skeleton
from .trace import TraceParams, traced_skeleton
from .twigs import TwigParams, add_twigs
from .tracks import Tracker, TrackParams, Tracks, detect_corners
from .tree3d import Tree3D, image_to_plane, pipe_radii
from .video import VideoInfo, iter_frames, open_video, parse_frame_range, prefetch

SKELETON_KINDS = ("traced", "paper")


@dataclass
class Settings:
    """Everything a run needs besides the input files."""

    levels: int = 6
    skeleton: str = "traced"
    fold_alpha: float = 0.4         # paper skeleton: x'_i += α (x'_j − x'_i)
    frames: str | None = None       # "A:B", 0-based, B exclusive
    scale: float = 1.0              # downscale factor for the video (0 < scale <= 1)
    cache_dir: str | None = None    # keep tracks + hierarchy here, keyed by video and settings
    track: TrackParams = field(default_factory=TrackParams)
    trace: TraceParams = field(default_factory=TraceParams)
    lift: LiftParams = field(default_factory=LiftParams)
    motion: MotionParams = field(default_factory=MotionParams)
    height_m: float = 10.0          # the tree's height in the scene, metres
    tip_radius: float = 0.0025      # branch radius at the tips, share of the height (pipe model)
    pipe_exponent: float = 2.0      # r_parent^e = Σ r_child^e
    twigs: TwigParams = field(default_factory=TwigParams)   # depth 0: no twigs
    curliness: float = 0.0          # branch mesh: minimum-jerk bend, 0..1 (recorded in meta["mesh"])
    bark: str = "none"              # branch mesh: "none", "smooth" or "rough" (recorded in meta["mesh"])
    leaves: LeafParams | None = field(default_factory=LeafParams)   # None: bare branches
    fit_branches: bool = True       # branch widths and centre lines measured in frame 1 (branch_fit)


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
    if not 0 <= s.twigs.depth <= 6:
        raise InputError(f"twig depth {s.twigs.depth} out of range; use 0..6 (0: no twigs)")
    from .branch_mesh import MeshParams, check_params
    check_params(MeshParams(curliness=s.curliness, bark=s.bark))
    if s.leaves is not None:
        from .leaves import check_leaf_params
        check_leaf_params(s.leaves)


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


def run(video: str, outline_path, settings: Settings | None = None,
        progress: ProgressFn | None = None) -> Result:
    """Video + outline → tracks, hierarchy and moving 2D skeleton. Raises InputError on bad input.

    ``outline_path``: a polygon .json or mask image path, ``"auto"`` (what sways in the first
    seconds, :mod:`.auto_outline`), or a polygon ``(M, 2)`` array in pixels of the original video
    (e.g. from a Blender Mask)."""
    s = settings or Settings()
    check_settings(s)
    info = open_video(video, s.scale)
    start, stop = parse_frame_range(s.frames, info.frame_count)
    if isinstance(outline_path, str) and outline_path == "auto":
        from .auto_outline import auto_outline
        outline = auto_outline(info, start)
    elif isinstance(outline_path, (str, os.PathLike)):
        outline = load_outline(outline_path, info.width, info.height, s.scale)
    else:
        outline = polygon_outline(np.asarray(outline_path, float) * s.scale, info.width, info.height)
    cached = key = None
    if s.cache_dir:
        key = cache.stage_key(video, outline.mask, start, stop, s.scale, s.track, s.levels)
        cached = cache.load(s.cache_dir, key)
    if cached is not None:
        tracks, maps, hier = cached
        report(progress, "tracking (cached)", 0.85)
    else:
        tracks, maps = track_video(info, outline, start, stop, s.track, sub_progress(progress, 0.0, 0.7))
        hier = build_hierarchy(tracks, HierarchyParams(levels=s.levels), sub_progress(progress, 0.7, 0.85))
        if key is not None:
            try:
                cache.save(s.cache_dir, key, tracks, maps, hier)
            except OSError:
                pass                # a cache that cannot be written only costs time
    sk_prog = sub_progress(progress, 0.85, 1.0)
    if s.skeleton == "paper":
        skel = paper_skeleton(tracks, hier, outline, alpha=s.fold_alpha, progress=sk_prog)
    else:
        skel = traced_skeleton(tracks, hier, outline, maps, s.trace, sk_prog)
    return Result(info, outline, start, stop, tracks, hier, maps, skel)


def build_3d(res: Result, s: Settings | None = None, name: str = "Tree",
             progress: ProgressFn | None = None) -> Tree3D:
    """Lift the 2D skeleton to 3D and solve its motion; the tree in metres, ``height_m`` tall."""
    s = s or Settings()
    if not s.height_m > 0:
        raise InputError(f"tree height {s.height_m} m is not positive; give e.g. 10")
    sk = res.skeleton
    frame = first_frame(res)
    fit = radius_px = tmap = None
    if s.fit_branches and frame is not None:
        tmap = tree_map(frame, res.outline.mask)
        if tmap is not None:
            fit = measure_branches(sk.parents, sk.nodes2d[0], tmap)
            vf = fit_to_video(sk.parents, sk.level, sk.nodes2d[0], fit, s.pipe_exponent)
            radius_px = vf.radius_px
            if radius_px is not None:               # onto the branches' centre lines, every frame
                sk = replace(sk, nodes2d=(sk.nodes2d + vf.shift_px[None]).astype(np.float32))
    lifted = lift(sk, res.outline, s.lift, sub_progress(progress, 0.0, 0.2))
    base = sk.nodes2d[0, 0].astype(float)
    targets = image_to_plane(sk.nodes2d.astype(float), base)[..., [0, 2]]
    mo = solve_motion(lifted.nodes, sk.parents, sk.level, targets, s.motion, sub_progress(progress, 0.2, 1.0))
    height_px = max(float(lifted.envelope.z.max()), float(lifted.nodes[:, 2].max()), 1.0)
    scale = s.height_m / height_px
    if radius_px is not None:
        radius = (radius_px * scale).astype(np.float32)
    else:
        radius = pipe_radii(sk.parents, s.tip_radius * s.height_m, s.pipe_exponent)
    meta = {"height_px": height_px, "metres_per_px": scale, "solver": s.motion.solver,
            "conifer": s.lift.conifer, "mu_deg": float(np.degrees(lifted.mu)),
            "envelope": envelope_to_meta(lifted.envelope, scale),
            "mesh": {"curliness": float(s.curliness), "bark": s.bark, "seed": int(s.twigs.seed)},
            "base_px": [float(base[0]), float(base[1])],          # trunk base in frame 1 (x, y) px
            "video_size": [int(res.outline.mask.shape[1]), int(res.outline.mask.shape[0])]}
    tree = Tree3D(sk.parents.copy(), (mo.nodes * scale).astype(np.float32), radius, sk.level.copy(),
                  sk.fps, name, meta)
    if fit is not None:
        meta["branch_fit"] = {"measured": fit.n_measured, "radii": radius_px is not None,
                              "trusted": int(vf.trusted.sum()),
                              "tree_share": round(fit.tree_share, 4)}
    tree_px = tmap.tree if tmap is not None else None
    tree = add_twigs(tree, s.twigs, progress, tree_px)  # after the motion solve, before the leaves
    return add_leaves(res, tree, s, frame, tree_px)


def first_frame(res: Result) -> np.ndarray | None:
    """Frame 1 of the run (BGR uint8, the outline's size), or None when it cannot be read again."""
    frame = next(iter_frames(res.info, res.start, res.start + 1), None)
    if frame is None:
        return None
    mask = res.outline.mask
    if frame.shape[:2] != mask.shape:
        frame = cv2.resize(frame, mask.shape[::-1], interpolation=cv2.INTER_AREA)
    return frame


def add_leaves(res: Result, tree: Tree3D, s: Settings, frame: np.ndarray | None = None,
               tree_px: np.ndarray | None = None) -> Tree3D:
    """Leaf clusters from the frame-1 Harris points (``tree.leaves``, placed from the tree's
    ``meta["base_px"]`` as :func:`build_3d` records it); the tree unchanged when ``s.leaves`` is
    None or frame 1 cannot be read again. ``frame`` frame 1 if already read."""
    if s.leaves is None:
        return tree
    if frame is None:
        frame = first_frame(res)
    if frame is None:
        return tree
    mask = res.outline.mask
    # the paper's seeds: frame 1's Harris corners inside the outline (all of them, not only
    # those that tracked well through the clip)
    points = detect_corners(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), mask, s.track)
    # the tree's own base (the branch fit may have moved the trunk onto its centre line)
    tree.leaves = place_leaves(tree, points, frame, np.asarray(tree.meta["base_px"], float), s.leaves,
                               mask, tree_px)
    return tree
