"""Stage 3 — Harris corners inside the outline, tracked with pyramidal Lucas–Kanade.

The tracker is fed one frame at a time (the pipeline streams the video once). Global camera
motion is estimated from features *outside* the outline and removed, so every position in
:class:`Tracks` is in frame-1 pixel coordinates. Lost points stay in the arrays and are marked
invalid (never silently dropped); once lost, a track stays lost. Where the live tracks have
thinned (leaf flutter, flicker and occluders kill them within seconds in real wind), new corners are
detected every few frames: each track has its own span (``valid`` is False before its birth), and
a track born late has, as its frame-1 row, an estimated reference: where it is now minus the
displacement of the live tracks around it, so displacements stay comparable across tracks.
Once :attr:`TrackParams.max_tracks` columns exist, new tracks take the columns of lost late tracks.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import cv2
import numpy as np

from ..outline import Outline
from .dense_flow import AnchoredFlow, FlowAccumulator

#: px: a crown whose tracks' sway (75th percentile of their displacement std) is below this is
#: below what Lucas-Kanade resolves (its noise is ~0.02-0.05 px on a still tree)
STILL_SWAY_PX = 0.12

LK_PARAMS = dict(winSize=(11, 11), maxLevel=3,
                 criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.02))


@dataclass
class TrackParams:
    """Tracking settings. Distances in pixels."""

    max_corners: int = 3000
    quality: float = 0.0002       # Harris response relative to the strongest corner
    min_distance: float = 3.0     # px between corners
    fb_max_error: float = 1.0     # px forward–backward disagreement that marks a point lost
    outlier_frac: float = 0.06    # of crown size: motion beyond neighbours' that marks an outlier
    jerk_frac: float = 0.006      # of crown size: a sudden change of per-frame step that marks a
                                  # track grabbed by something passing in front (at least 6x its usual)
    neighbours: int = 8           # tracks compared against for the outlier test
    stabilize: bool = True        # remove camera motion using features outside the outline
    max_tree_px: int = 480        # track on frames scaled so the outline's larger side is at most
                                  # this (large and 4K videos: corners and LK cost scale with it)
    light_sigma: float = 4.0      # px (working image): LK runs on the frame minus its blur at this
                                  # scale, rescaled to a fixed contrast, so a gain or offset change
                                  # (flicker, a cloud shadow) is not motion; 0: the raw grey frame
    redetect_every: int = 4       # frames between checks for thinned tracks (0: never re-detect)
    redetect_below: float = 0.6   # a grid cell over the crown is refilled when its live tracks fall
                                  # below this share of its frame-1 count
    flow_hz: float = 7.5          # dense flow from frame 1 (dense_flow.py) at most this often a
                                  # second, fused with the tracks per node; 0: tracks only
    flow_max_px: float = 320.0    # the tree's larger side in the flow's images (its cost grows
                                  # with their area; its gains were measured at 260-320 px)
    max_tracks: int = 12000       # columns of the track arrays (memory: F x this x 9 bytes); once
                                  # they are all used, a new track takes the column of a late track
                                  # already lost (a 1080p clip in wind reaches 12000 in ~12 s)


@dataclass
class Tracks:
    """Tracked Harris corners.

    ``points (F, P, 2)`` float32 pixels in frame-1 coordinates (camera motion removed); a track
    born after frame 1 has its estimated frame-1 reference in row 0 and in every row before its
    birth; ``valid (F, P)`` bool (False before birth and after loss); ``camera (F, 2, 3)``
    float32 affine maps from each frame's image to frame 1; ``intensity (P,)`` float32 grey level
    0..255 at each corner where it was first seen;
    ``fps`` frames per second; ``start`` first frame index of the range; ``size`` (width, height);
    ``times (F,)`` seconds from the first frame (the frames' timestamps; None: ``index / fps``);
    ``flow`` the dense flow from frame 1 (:mod:`.dense_flow`; None: tracks only).

    A column holds one track, or, once :attr:`TrackParams.max_tracks` columns exist, several late
    tracks one after another: each run of valid frames is one track, born where it starts (with
    at least one invalid frame between two; row 0 is the last one's reference). Frame 1's tracks
    (:meth:`initial`) always have a column to themselves.
    """

    points: np.ndarray
    valid: np.ndarray
    camera: np.ndarray
    intensity: np.ndarray
    fps: float
    start: int
    size: tuple[int, int]
    warnings: list[str] = field(default_factory=list)
    times: np.ndarray | None = None
    flow: AnchoredFlow | None = None

    @property
    def n_frames(self) -> int:
        return self.points.shape[0]

    @property
    def n_tracks(self) -> int:
        """Tracks started over the clip (a column may hold several, one after another)."""
        return int(self.births().sum())

    def births(self) -> np.ndarray:
        """``(F, P)`` bool: a track starts in that frame and column (valid, and not in the frame
        before)."""
        born = self.valid.copy()
        born[1:] &= ~self.valid[:-1]
        return born

    def initial(self) -> np.ndarray:
        """Indices of the tracks detected in frame 1 (the hierarchy and the skeleton's geometry
        are built on them; later tracks only add motion)."""
        return np.flatnonzero(self.valid[0])

    def displacement(self) -> np.ndarray:
        """``(F, P, 2)`` pixels moved since frame 1, NaN where invalid (a column's earlier tracks
        too: row 0 is its last track's reference)."""
        d = self.points - self.points[:1]
        return np.where(self.last_span()[..., None], d, np.nan)

    def last_span(self) -> np.ndarray:
        """``(F, P)`` bool: the frames of each column's last track (``valid`` where a column held
        one track)."""
        starts = self.births()
        F = len(starts)
        last = F - 1 - np.argmax(starts[::-1], axis=0)          # the last start (F - 1: none)
        return self.valid & (np.arange(F)[:, None] >= last[None, :])

    def track_sway(self) -> np.ndarray:
        """``(P,)`` px: each column's last track's sway, the std of its displacement over the frames
        it is valid (NaN for tracks valid in fewer than 3 frames)."""
        d = self.displacement()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            s = np.nanstd(d, axis=0)
        s = np.sqrt(np.nansum(s ** 2, axis=-1))
        return np.where(self.last_span().sum(0) >= 3, s, np.nan)

    def sway_px(self) -> float:
        """Typical sway: median over tracks of the std of their displacement (pixels)."""
        s = self.track_sway()
        ok = np.isfinite(s)
        return float(np.median(s[ok])) if ok.any() else 0.0


def detect_corners(gray: np.ndarray, mask: np.ndarray, params: TrackParams, max_corners: int | None = None) -> np.ndarray:
    """Harris corners ``(P, 2)`` float32 inside ``mask`` (``cv2.goodFeaturesToTrack``; at most
    ``max_corners``, default ``params.max_corners``). Detected on the mask's bounding box plus a
    margin wider than the operator's reach (3 px block, 3 px Sobel): the same corners as on the
    whole frame (the quality threshold is relative to the strongest corner inside the mask),
    without the whole frame's response images (a 4K frame's are ~100 MB)."""
    rows, cols = np.flatnonzero(mask.any(1)), np.flatnonzero(mask.any(0))
    if len(rows) == 0:
        return np.zeros((0, 2), np.float32)
    h, w = mask.shape
    y0, y1 = max(0, rows[0] - 4), min(h, rows[-1] + 5)
    x0, x1 = max(0, cols[0] - 4), min(w, cols[-1] + 5)
    pts = cv2.goodFeaturesToTrack(np.ascontiguousarray(gray[y0:y1, x0:x1]),
                                  maxCorners=params.max_corners if max_corners is None else max_corners,
                                  qualityLevel=params.quality, minDistance=params.min_distance,
                                  mask=np.ascontiguousarray(mask[y0:y1, x0:x1]).astype(np.uint8),
                                  blockSize=3, useHarrisDetector=True, k=0.04)
    if pts is None:
        return np.zeros((0, 2), np.float32)
    return (pts.reshape(-1, 2) + np.array([x0, y0], np.float32)).astype(np.float32)


def lk_forward_backward(prev: np.ndarray, cur: np.ndarray, pts: np.ndarray,
                        max_error: float) -> tuple[np.ndarray, np.ndarray]:
    """Track ``pts (P, 2)`` from ``prev`` to ``cur`` grey images; returns new points and ok (P,)."""
    if len(pts) == 0:
        return pts.copy(), np.zeros(0, bool)
    p0 = pts.reshape(-1, 1, 2)
    p1, st1, _ = cv2.calcOpticalFlowPyrLK(prev, cur, p0, None, **LK_PARAMS)
    p0r, st2, _ = cv2.calcOpticalFlowPyrLK(cur, prev, p1, None, **LK_PARAMS)
    fb = np.linalg.norm((p0r - p0).reshape(-1, 2), axis=1)
    ok = (st1.ravel() == 1) & (st2.ravel() == 1) & (fb < max_error)
    return p1.reshape(-1, 2), ok


def nan_median_rows(a: np.ndarray) -> np.ndarray:
    """Median over axis 1 of ``a (P, K, C)`` ignoring NaN (NaN where a row has none): a fast
    ``np.nanmedian(a, axis=1)``. ``K`` may be 0 (no neighbours): all NaN."""
    if a.shape[1] == 0:
        return np.full((a.shape[0], a.shape[2]), np.nan, a.dtype if a.dtype.kind == "f" else float)
    s = np.sort(a, axis=1)                          # NaN sorts last
    n = (~np.isnan(a)).sum(axis=1)                  # (P, C)
    lo = np.clip((n - 1) // 2, 0, a.shape[1] - 1)[:, None, :]
    hi = np.clip(n // 2, 0, a.shape[1] - 1)[:, None, :]
    med = 0.5 * (np.take_along_axis(s, lo, 1) + np.take_along_axis(s, hi, 1))[:, 0, :]
    return np.where(n > 0, med, np.nan)


def apply_affine(m: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Apply a ``(2, 3)`` affine to ``pts (..., 2)``."""
    return pts @ m[:, :2].T + m[:, 2]


class CameraEstimator:
    """Tracks background corners (outside the outline) and estimates image→frame-1 affines."""

    def __init__(self, gray0: np.ndarray, tree_mask: np.ndarray, params: TrackParams):
        h, w = gray0.shape
        pad = max(3, int(0.02 * max(h, w)))
        bg = ~cv2.dilate(tree_mask.astype(np.uint8), np.ones((2 * pad + 1,) * 2, np.uint8)).astype(bool)
        bg[:pad], bg[-pad:], bg[:, :pad], bg[:, -pad:] = False, False, False, False
        self.bg_mask = bg
        self.params = params
        self.pts = self._detect(gray0)
        self.ref = self.pts.copy()          # the same points in frame-1 coordinates
        self.current = np.array([[1.0, 0, 0], [0, 1.0, 0]])
        self.available = len(self.pts) >= 8
        self.moved = False                  # strong evidence of camera motion seen yet
        self.diag = float(np.hypot(h, w))

    def _detect(self, gray: np.ndarray) -> np.ndarray:
        pts = cv2.goodFeaturesToTrack(gray, maxCorners=400, qualityLevel=0.01, minDistance=8,
                                      mask=self.bg_mask.astype(np.uint8), blockSize=5)
        return np.zeros((0, 2), np.float32) if pts is None else pts.reshape(-1, 2).astype(np.float32)

    def _strong(self, m: np.ndarray, cur: np.ndarray, ref: np.ndarray, inl: np.ndarray | None,
                moving: bool) -> bool:
        """Whether the background supports the estimate ``m``: most tracked background points
        agree (RANSAC inliers ≥ half, at least 8) and they are spread over the frame (RMS distance
        from their centre ≥ 10 % of its diagonal: not one object passing by); until the camera has
        been seen ``moving``, the motion must also beat the identity by more than the fit's own
        noise (median residual of identity > 2 × the model's + 0.1 px). Otherwise the estimate is
        noise, a leaf or a passer-by: a tripod gets no camera motion."""
        if inl is None:
            return False
        keep = inl.ravel().astype(bool)
        if keep.sum() < max(8, 0.5 * len(keep)):
            return False
        c, r = cur[keep].astype(np.float64), ref[keep].astype(np.float64)
        if np.sqrt(((c - c.mean(0)) ** 2).sum(1).mean()) < 0.1 * self.diag:
            return False
        if moving:
            return True
        r_id = float(np.median(np.linalg.norm(c - r, axis=1)))
        r_m = float(np.median(np.linalg.norm(apply_affine(m, c) - r, axis=1)))
        return r_id > 2.0 * r_m + 0.1

    def update(self, prev: np.ndarray, cur: np.ndarray) -> np.ndarray:
        """Estimate the ``(2, 3)`` affine mapping ``cur`` image coordinates to frame 1."""
        if not self.available:
            return self.current
        new, ok = lk_forward_backward(prev, cur, self.pts, self.params.fb_max_error)
        return self.update_tracked(new, ok, cur)

    def update_tracked(self, new: np.ndarray, ok: np.ndarray, cur: np.ndarray) -> np.ndarray:
        """Like :meth:`update`, given ``self.pts`` already tracked into ``cur`` (new, ok)."""
        if not self.available:
            return self.current
        if ok.sum() >= 8:
            m, inl = cv2.estimateAffinePartial2D(new[ok], self.ref[ok], method=cv2.RANSAC,
                                                 ransacReprojThreshold=1.0, maxIters=2000, confidence=0.99)
            if m is not None and self._strong(m, new[ok], self.ref[ok], inl, self.moved):
                self.current, self.moved = m, True
            elif not self.moved:
                self.current = np.array([[1.0, 0, 0], [0, 1.0, 0]])   # a tripod: never invent a drift
        self.pts, self.ref = new[ok], self.ref[ok]
        if len(self.pts) < 100:   # refill: new corners get frame-1 coordinates through the estimate
            fresh = self._detect(cur)
            self.pts = np.vstack([self.pts, fresh]).astype(np.float32)
            self.ref = np.vstack([self.ref, apply_affine(self.current, fresh)]).astype(np.float32)
        return self.current


class Tracker:
    """Streaming tracker: ``Tracker(frame0, outline)``, then ``feed(frame)`` per frame, ``result()``."""

    def __init__(self, frame0: np.ndarray, outline: Outline, fps: float, start: int = 0,
                 params: TrackParams | None = None, trees: np.ndarray | None = None):
        """``trees (H, W)`` bool frame px: every tree of the shot (default the outline's), kept out of
        the background the camera is measured on (the other trees sway too)."""
        self.params = params or TrackParams()
        x0, y0, x1, y1 = outline.bbox
        self.crown = float(max(x1 - x0, y1 - y0))
        # working scale: LK runs on frames scaled by s; every stored position is in frame px
        self.s = min(1.0, self.params.max_tree_px / max(self.crown, 1.0))
        gray = self._gray(frame0)
        mask = outline.mask
        if self.s < 1.0:
            mask = cv2.resize(mask.astype(np.uint8), (gray.shape[1], gray.shape[0]),
                              interpolation=cv2.INTER_NEAREST) > 0
        self.mask = mask                            # the outline in the working image
        self.prev = self._lk_image(gray)
        self.prev_raw = gray
        raw = detect_corners(gray, mask, self.params)
        pts = (raw / self.s).astype(np.float32)
        self.fps, self.start, self.size = fps, start, (frame0.shape[1], frame0.shape[0])
        self.raw = raw                              # current positions in the working image
        self.ref = pts.copy()                       # frame-1 reference of every track (P, 2)
        self.points = [pts.copy()]                  # per frame: (P_t, 2) for the P_t tracks born so far
        self.valid = [np.ones(len(pts), bool)]
        self.camera = [np.array([[1.0, 0, 0], [0, 1.0, 0]])]
        full = frame0 if frame0.ndim == 2 else cv2.cvtColor(frame0, cv2.COLOR_BGR2GRAY)
        self.intensity = self._sample(full, pts)
        not_bg = mask
        if trees is not None:
            not_bg = mask | (cv2.resize(np.asarray(trees, np.uint8), (gray.shape[1], gray.shape[0]),
                                        interpolation=cv2.INTER_NEAREST) > 0)
        self.cam = CameraEstimator(gray, not_bg, self.params) if self.params.stabilize else None
        self.alive = np.ones(len(pts), bool)
        self.n_initial = len(pts)                    # frame 1's tracks: columns never reused
        self._live_neighbours()
        self.step = np.full((len(pts), 2), np.nan, np.float32)   # last stabilized step, px
        self.jerk = np.zeros(len(pts), np.float32)               # running mean |Δ step|, px
        self.resid = [np.zeros(len(pts), np.float32)]            # per frame: motion beyond neighbours
        self._grid_init(raw)
        # the dense flow from frame 1: computed by the caller (run.track_video does it in the
        # decoding thread, FlowAccumulator.compute), kept with the tracks
        self.flow = FlowAccumulator(gray, outline.bbox, self.s, self.params.flow_hz, self.params.flow_max_px)

    @staticmethod
    def _sample(gray: np.ndarray, pts: np.ndarray) -> np.ndarray:
        """Grey levels ``(P,)`` float32 of ``gray`` at ``pts (P, 2)`` (nearest pixel)."""
        return gray[np.clip(pts[:, 1].round().astype(int), 0, gray.shape[0] - 1),
                    np.clip(pts[:, 0].round().astype(int), 0, gray.shape[1] - 1)].astype(np.float32)

    def _grid_init(self, raw: np.ndarray) -> None:
        """The crown's re-detection grid (about 12 × 12 cells over the outline, working px) and its
        frame-1 corner count per cell."""
        h, w = self.mask.shape
        self.cell = max(8.0, self.crown * self.s / 12.0)
        self.grid = (int(np.ceil(h / self.cell)), int(np.ceil(w / self.cell)))
        self.count0 = self._cell_counts(raw)

    def _cell_counts(self, pts: np.ndarray) -> np.ndarray:
        gy, gx = self.grid
        iy = np.clip((pts[:, 1] / self.cell).astype(int), 0, gy - 1)
        ix = np.clip((pts[:, 0] / self.cell).astype(int), 0, gx - 1)
        return np.bincount(iy * gx + ix, minlength=gy * gx)

    def _gray(self, frame: np.ndarray) -> np.ndarray:
        """Working grey image from a BGR frame ``(H, W, 3)`` or a grey one ``(H, W)``."""
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame
        if self.s < 1.0:
            gray = cv2.resize(gray, None, fx=self.s, fy=self.s, interpolation=cv2.INTER_LINEAR)
        return gray

    def _lk_image(self, gray: np.ndarray) -> np.ndarray:
        """The image LK tracks on: ``gray`` minus its Gaussian blur (``light_sigma``), scaled so its
        robust spread is fixed, as uint8 around 128. Local offset and gain (flicker, a drifting
        shadow) cancel; edges and texture stay. ``light_sigma`` 0: ``gray`` itself."""
        sig = self.params.light_sigma
        if sig <= 0:
            return gray
        g = gray.astype(np.float32)
        h, w = g.shape
        # the blur on the half-size image, back by bilinear interpolation (σ on the half: the rest
        # of sig after the halving's 0.5 px): within 2 grey levels of the full-size blur at 99 % of
        # pixels, a quarter of its time
        half = cv2.resize(g, ((w + 1) // 2, (h + 1) // 2), interpolation=cv2.INTER_AREA)
        half = cv2.GaussianBlur(half, (0, 0), float(np.sqrt(max(sig * sig - 0.25, 0.25))) / 2.0)
        hp = g - cv2.resize(half, (w, h), interpolation=cv2.INTER_LINEAR)
        spread = float(np.percentile(np.abs(hp[::4, ::4]), 90)) + 1e-3   # the frame's contrast, from
                                                                          # a 16th of its pixels
        hp *= 40.0 / spread                                 # in place: the same numbers as
        hp += 128.0                                         # clip(hp * k + 128, 0, 255), a fifth
        np.clip(hp, 0, 255, out=hp)                         # of the time
        return hp.astype(np.uint8)

    def _neighbours(self, pts: np.ndarray, among: np.ndarray | None = None,
                    rows: np.ndarray | None = None) -> np.ndarray:
        """``(R, k)`` indices of the nearest others of the points ``rows`` (default: all) of ``pts``,
        among the ``among`` mask if given."""
        rows = np.arange(len(pts)) if rows is None else rows
        cand = np.arange(len(pts)) if among is None else np.flatnonzero(among)
        k = min(self.params.neighbours, max(len(cand) - 1, 0))
        if k == 0:
            return np.zeros((len(rows), 0), int)
        from scipy.spatial import cKDTree
        _, idx = cKDTree(pts[cand]).query(pts[rows], k=k + 1)
        idx = cand[idx]
        # drop each point itself (where it is among the candidates), keep k others
        own = idx == rows[:, None]
        order = np.argsort(own, axis=1, kind="stable")
        return np.take_along_axis(idx, order, 1)[:, :k]

    def _live_neighbours(self) -> None:
        """Neighbours of the live tracks among the live tracks (``nbr``, for the rows ``nbr_rows``):
        a track once lost never comes back, so the dead need none."""
        self.nbr_rows = np.flatnonzero(self.alive)
        self.nbr = self._neighbours(self.points[-1], self.alive, self.nbr_rows)

    def prepare(self, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The images :meth:`feed` needs from ``frame`` (BGR ``(H, W, 3)`` or grey ``(H, W)``
        uint8): its full-size grey, the working grey and the LK image. Reads only settings fixed
        at construction, so another thread may prepare the next frame while one is fed (the
        pipeline does it in the decoding thread: OpenCV and numpy release the GIL)."""
        full = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        raw_gray = self._gray(full)
        return full, raw_gray, self._lk_image(raw_gray)

    def feed(self, frame: np.ndarray | None, dt: float = 1.0,
             prepared: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> None:
        """Track every live point into ``frame`` (BGR ``(H, W, 3)`` or grey ``(H, W)`` uint8, or
        None with ``prepared``, its :meth:`prepare` images); ``dt`` the time since the previous
        frame in nominal frame intervals (variable frame rate: the jerk test compares speeds, not
        steps)."""
        if prepared is None:
            assert frame is not None
            prepared = self.prepare(frame)
        full, raw_gray, gray = prepared
        n = len(self.raw)
        bg = self.cam.pts if self.cam is not None and self.cam.available else np.zeros((0, 2), np.float32)
        live = np.flatnonzero(self.alive)
        if gray is raw_gray:          # one LK call for tree and background: pyramids built once
            new_l, ok_l = lk_forward_backward(self.prev, gray, np.vstack([self.raw[live], bg]).astype(np.float32),
                                              self.params.fb_max_error)
            bg_new, bg_ok, new_l, ok_l = new_l[len(live):], ok_l[len(live):], new_l[:len(live)], ok_l[:len(live)]
        else:                         # the tree on the light-normalized frames, the background on
            new_l, ok_l = lk_forward_backward(self.prev, gray, self.raw[live], self.params.fb_max_error)  # grey
            bg_new, bg_ok = lk_forward_backward(self.prev_raw, raw_gray, bg, self.params.fb_max_error)
        cam = self.cam.update_tracked(bg_new, bg_ok, raw_gray) if self.cam is not None else self.camera[0]
        cam = np.array(cam, float)
        cam[:, 2] /= self.s           # the working image's affine, in frame px
        ok = np.zeros(n, bool)
        ok[live] = ok_l
        self.alive &= ok
        self.raw[live[ok_l]] = new_l[ok_l]
        stab = apply_affine(cam, self.raw / self.s).astype(np.float32)
        self._reject_jerks(stab, dt)
        self._reject_outliers(stab)
        self.points.append(stab)
        self.valid.append(self.alive.copy())
        self.camera.append(cam)
        self.prev, self.prev_raw = gray, raw_gray
        every = self.params.redetect_every
        if every > 0 and (len(self.points) - 1) % every == 0:
            self._refill(raw_gray, full, cam)

    def _free_columns(self) -> np.ndarray:
        """Columns a new track may take once ``max_tracks`` columns exist: those of tracks born after
        frame 1 and lost before the previous frame (so no step joins two tracks; frame 1's tracks,
        which the hierarchy reads whole, are never reused); none while there is room."""
        if len(self.raw) < self.params.max_tracks or len(self.valid) < 2:
            return np.zeros(0, int)
        before = self.valid[-2]
        late = np.arange(len(before)) >= self.n_initial
        return np.flatnonzero(late & ~before)

    def _refill(self, gray: np.ndarray, full: np.ndarray, cam: np.ndarray) -> None:
        """Detect new corners where the live tracks have thinned (grid cells over the crown below
        ``redetect_below`` of their frame-1 count), away from live tracks, inside the outline
        moved with the crown; they are born in the current frame."""
        prm = self.params
        free = self._free_columns()
        room = prm.max_tracks - len(self.raw) + len(free)
        if room <= 0:
            return
        stab = self.points[-1]
        ref_w = (stab - self.ref) * self.s             # working px: each track's displacement
        alive_now = self.alive
        # cells in frame-1 coordinates (the crown as it stood), counted at each live track's reference
        count = self._cell_counts(self.ref[alive_now] * self.s)
        need = (self.count0 >= 2) & (count < prm.redetect_below * self.count0)
        deficit = int((self.count0 - count)[need].sum())
        if deficit < max(4, 0.02 * self.count0.sum()):
            return
        h, w = self.mask.shape
        iy = np.minimum((np.arange(h) / self.cell).astype(int), self.grid[0] - 1)
        ix = np.minimum((np.arange(w) / self.cell).astype(int), self.grid[1] - 1)
        region = need.reshape(self.grid)[iy[:, None], ix[None, :]].astype(np.uint8)
        region &= self.mask.astype(np.uint8)
        # the crown has moved since frame 1: shift the region by the live tracks' median
        # displacement, and back through the camera into the current image; keep a margin
        # inside the outline's edge the size of the crown's spread of displacements
        shift = np.median(ref_w[alive_now], axis=0) if alive_now.any() else np.zeros(2)
        inv = cv2.invertAffineTransform(np.asarray(cam, np.float64) * [[1, 1, self.s], [1, 1, self.s]])
        inv[:, 2] += inv[:, :2] @ shift
        region = cv2.warpAffine(region, inv, (w, h), flags=cv2.INTER_NEAREST)
        spread = float(np.percentile(np.linalg.norm(ref_w[alive_now] - shift, axis=1), 90)) if alive_now.any() else 0.0
        margin = int(np.clip(round(spread), 1, 0.05 * self.crown * self.s))
        region = cv2.erode(region, np.ones((2 * margin + 1,) * 2, np.uint8))
        occupied = np.zeros((h, w), np.uint8)
        live = self.raw[alive_now].round().astype(int)
        inside = (live[:, 0] >= 0) & (live[:, 0] < w) & (live[:, 1] >= 0) & (live[:, 1] < h)
        occupied[live[inside, 1], live[inside, 0]] = 1
        r = max(1, int(round(prm.min_distance)))
        occupied = cv2.dilate(occupied, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
        region[occupied > 0] = 0
        if not region.any():
            return
        raw = detect_corners(gray, region, prm, min(deficit, room))
        if len(raw) == 0:
            return
        st = apply_affine(cam, raw / self.s).astype(np.float32)
        # frame-1 reference: minus the displacement of the live tracks around it
        nb = self._neighbours(np.vstack([stab, st]), np.concatenate([alive_now, np.zeros(len(st), bool)]),
                              np.arange(len(stab), len(stab) + len(st)))
        disp = np.where(alive_now[nb][..., None], (stab - self.ref)[nb], np.nan)
        est = nan_median_rows(disp)
        ref = (st - np.nan_to_num(est)).astype(np.float32)
        # once the cap is reached, lost late tracks' columns first; the rest in new columns at the end
        reuse = min(len(raw), len(free))
        m = len(raw) - reuse
        n = len(self.raw)
        self._add_columns(m)
        cols = np.concatenate([free[:reuse], np.arange(n, n + m)])
        self.raw[cols], self.ref[cols], self.points[-1][cols] = raw, ref, st
        self.valid[-1][cols] = True
        self.resid[-1][cols] = 0.0
        self.alive[cols] = True
        self.step[cols] = np.nan
        self.jerk[cols] = 0.0
        self.intensity[cols] = self._sample(full, raw / self.s)
        self._live_neighbours()

    def _add_columns(self, m: int) -> None:
        """``m`` more columns in every per-track array (their values are set by the caller)."""
        if m <= 0:
            return
        two, one = np.zeros((m, 2), np.float32), np.zeros(m, np.float32)
        self.raw, self.ref, self.step = (np.vstack([a, two]) for a in (self.raw, self.ref, self.step))
        self.points[-1] = np.vstack([self.points[-1], two])
        self.valid[-1] = np.concatenate([self.valid[-1], np.zeros(m, bool)])
        self.alive = np.concatenate([self.alive, np.zeros(m, bool)])
        self.resid[-1], self.jerk, self.intensity = (np.concatenate([a, one])
                                                     for a in (self.resid[-1], self.jerk, self.intensity))

    def _reject_jerks(self, stab: np.ndarray, dt: float = 1.0) -> None:
        """Kill tracks whose per-frame step changes abruptly against the crown's (branches sway
        smoothly; a track dragged by a passer-by, or one that jumped to another corner when its
        leaf turned, changes speed from one frame to the next). The step is taken relative to the
        live tracks' median step, so a gust moving the crown as one jerks nothing, while a patch of
        tracks jumping together still does."""
        step = (stab - self.points[-1]) / max(dt, 1e-3)          # px per nominal frame
        if self.alive.any():
            step = step - np.median(step[self.alive], axis=0)
        change = np.linalg.norm(step - self.step, axis=1)
        floor = self.params.jerk_frac * self.crown
        bad = self.alive & np.isfinite(change) & (change > np.maximum(floor, 6.0 * self.jerk))
        self.jerk = np.where(np.isfinite(change), 0.9 * self.jerk + 0.1 * np.nan_to_num(change), self.jerk)
        self.step = np.where(self.alive[:, None], step, np.nan).astype(np.float32)
        self.alive &= ~bad

    def _reject_outliers(self, stab: np.ndarray) -> None:
        """Kill tracks that move far more than their spatial neighbours or beyond the crown.

        A track is dragged away gradually before it crosses the threshold, so the frames leading
        up to its death where it already strayed (over a quarter of the threshold) are invalidated
        too: node motion must not inherit the drag.
        """
        if self.nbr.shape[1] == 0:
            return
        keep = self.alive[self.nbr_rows]                  # rows still alive (tracks only ever die)
        rows, nbr = self.nbr_rows[keep], self.nbr[keep]
        disp = stab - self.ref
        d_n = np.where(self.alive[nbr][..., None], disp[nbr], np.nan)
        med = nan_median_rows(d_n)
        resid = np.zeros(len(stab), np.float32)
        resid[rows] = np.linalg.norm(disp[rows] - np.nan_to_num(med), axis=1)
        far = np.zeros(len(stab), bool)
        far[rows] = np.linalg.norm(disp[rows], axis=1) > 0.5 * self.crown
        thr = self.params.outlier_frac * self.crown
        bad = self.alive & ((resid > thr) | far)
        self.alive &= ~bad
        self.resid.append(resid)
        idx = np.flatnonzero(bad)
        for t in range(len(self.valid) - 1, 0, -1):
            idx = idx[idx < len(self.resid[t])]
            if len(idx) == 0:
                break
            idx = idx[self.resid[t][idx] > 0.25 * thr]
            self.valid[t][idx] = False

    def result(self) -> Tracks:
        """All frames fed so far as :class:`Tracks` (with a warning when the tree barely moves)."""
        F, P = len(self.points), len(self.ref)
        points = np.repeat(self.ref[None], F, axis=0)
        valid = np.zeros((F, P), bool)
        for t, (p, v) in enumerate(zip(self.points, self.valid)):
            points[t, :len(p)] = p
            valid[t, :len(v)] = v
        tr = Tracks(points, valid, np.stack(self.camera).astype(np.float32), self.intensity, self.fps,
                    self.start, self.size, flow=self.flow.result())
        if tr.points.shape[1] == 0:
            tr.warnings.append("no corners found inside the outline; check that it surrounds the tree")
        elif tr.n_frames > 2:
            s = tr.track_sway()
            s = s[np.isfinite(s)]
            # the crown's sway (the moving quarter of the tracks), against what LK resolves: a
            # still tree's tracks show only their noise (~0.02-0.05 px); a tree swaying a pixel a
            # second shows several tenths even on tracks that live a second
            sway = float(np.percentile(s, 75)) if len(s) else 0.0
            if sway < STILL_SWAY_PX:
                tr.warnings.append(
                    f"the tree barely moves (the crown's tracks sway {sway:.2f} px, below the "
                    f"{STILL_SWAY_PX} px tracking resolves); the hierarchy leans on position, the "
                    "motion will be faint — a windier clip gives a better model")
        if self.cam is not None and not self.cam.available:
            tr.warnings.append("too little background outside the outline to remove camera motion; "
                               "use a tripod clip or leave some background in frame")
        return tr
