"""Dense optical flow from frame 1, the nodes' second motion source (issue 18, item 3).

At most ``TrackParams.flow_hz`` times a second, DIS optical flow (OpenCV's ``DISOpticalFlow``,
preset medium) is computed from frame 1 to the frame and back, on the working grey frames cropped
to the outline's box and scaled so the tree is at most ``TrackParams.flow_max_px`` (the flow's
px); both fields are averaged onto a grid of :data:`STEP` px cells and blurred (σ = :data:`BLUR`
px in all), and each cell's forward–backward disagreement ``e(x) = |f(x) + b(x + f(x))|`` is kept
with the forward field (float16).

Anchored to frame 1, it never drifts; where leaves turn or the light changes it is wrong, and
says so through ``e``. Lucas–Kanade tracks are the other way round (a track follows its corner
through flutter, but a time gap of several frames — a dropped-frame clip — makes many jump to a
neighbour, and each keeps that error): :func:`.node_motion.fuse` weighs the two per node and
frame. Measured on the wind samples (2D tip correlation, tracks → fused): flutter 0.88 → 0.89,
flicker 0.89 → 0.91, variable frame rate 0.69 → 0.77 and 0.90 → 0.94.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

#: flow px: the blur of both flow fields (DIS's patches give a blocky field; the nodes average
#: tracks over a few px too)
BLUR = 3.0
#: flow px between the stored grid's samples (the blurred field varies slowly at this scale)
STEP = 4
#: grid cells: the blur on the grid that, after a cell's mean (σ² = STEP²/12), makes BLUR in all
GRID_SIGMA = float(np.sqrt(BLUR ** 2 - STEP ** 2 / 12.0) / STEP)
#: of the tree's size: the crop around the outline's box (the crown moves by up to ~10 % of its size)
MARGIN_FRAC = 0.12


@dataclass
class AnchoredFlow:
    """The flow from frame 1 to the frames ``frames (K,)`` (indices from the first tracked frame,
    increasing, frame 0 not included): ``disp (K, Gh, Gw, 2)`` float16 px, the image displacement
    in *frame* px (camera motion not removed); ``err (K, Gh, Gw)`` float16 forward–backward
    disagreement in the flow's own px (the tree at most ``TrackParams.flow_max_px``); grid sample
    (i, j) sits at frame px ``origin + step · (j, i)`` (``origin``, ``step`` (2,))."""

    frames: np.ndarray
    disp: np.ndarray
    err: np.ndarray
    origin: np.ndarray
    step: np.ndarray

    def sample(self, pts: np.ndarray, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
        """At frame-1 positions ``pts (N, 2)`` frame px: (displacement ``(n_frames, N, 2)`` frame px,
        disagreement ``(n_frames, N)`` flow px), bilinear on the grid and linear in time between
        the computed frames (frame 0: 0 and 0; after the last computed frame: its values)."""
        N = len(pts)
        d = np.zeros((n_frames, N, 2), np.float32)
        e = np.zeros((n_frames, N), np.float32)
        K = len(self.frames)
        if K == 0 or N == 0 or n_frames < 2:
            return d, e
        g = ((np.asarray(pts, np.float64) - self.origin) / self.step).astype(np.float32)
        gx, gy = g[:, 0].reshape(1, -1), g[:, 1].reshape(1, -1)
        dk = np.zeros((K + 1, N, 2), np.float32)        # row 0: frame 0
        ek = np.zeros((K + 1, N), np.float32)
        for k in range(K):
            f = self.disp[k].astype(np.float32)
            for c in range(2):
                dk[k + 1, :, c] = cv2.remap(f[..., c], gx, gy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).ravel()
            ek[k + 1] = cv2.remap(self.err[k].astype(np.float32), gx, gy, cv2.INTER_LINEAR,
                                  borderMode=cv2.BORDER_REPLICATE).ravel()
        at = np.concatenate([[0], self.frames]).astype(np.float64)
        t = np.arange(n_frames, dtype=np.float64)
        hi = np.clip(np.searchsorted(at, t), 1, K)
        lo = hi - 1
        a = np.clip((t - at[lo]) / np.maximum(at[hi] - at[lo], 1e-9), 0.0, 1.0).astype(np.float32)
        d[:] = (1 - a)[:, None, None] * dk[lo] + a[:, None, None] * dk[hi]
        e[:] = (1 - a)[:, None] * ek[lo] + a[:, None] * ek[hi]
        return d, e


class FlowAccumulator:
    """Computes :class:`AnchoredFlow` frame by frame. :meth:`compute` reads only what is fixed at
    construction (call it from the decoding thread, in frame order); :meth:`add` stores its result."""

    def __init__(self, gray0: np.ndarray, bbox: tuple[int, int, int, int], scale: float, hz: float,
                 max_px: float = 320.0) -> None:
        """``gray0`` the working grey of frame 1, ``bbox`` the outline's (x0, y0, x1, y1) frame px,
        ``scale`` working px per frame px, ``hz`` the most flows a second (0: none), ``max_px``
        the tree's larger side in the flow's images (the working crop is scaled down to it)."""
        h, w = gray0.shape[:2]
        x0, y0, x1, y1 = (np.asarray(bbox, np.float64) * scale).tolist()
        crown = max(x1 - x0, y1 - y0, 1.0)
        m = MARGIN_FRAC * crown
        self.x0, self.y0 = int(max(0, np.floor(x0 - m))), int(max(0, np.floor(y0 - m)))
        self.x1, self.y1 = int(min(w, np.ceil(x1 + m))), int(min(h, np.ceil(y1 + m)))
        r = min(1.0, float(max_px) / crown)
        gw = max(1, int(round((self.x1 - self.x0) * r / STEP)))
        gh = max(1, int(round((self.y1 - self.y0) * r / STEP)))
        self.grid_size = (gw, gh)
        self.flow_size = (gw * STEP, gh * STEP)           # the flow's images: whole grid cells
        # flow px per frame px, per axis
        self.fpx = np.array([self.flow_size[0] / (self.x1 - self.x0), self.flow_size[1] / (self.y1 - self.y0)]) * scale
        self.scale = float(scale)
        self.hz = float(hz)
        self.first = self._image(gray0)
        self.dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM) if hz > 0 else None
        self.gx, self.gy = np.meshgrid(np.arange(gw, dtype=np.float32), np.arange(gh, dtype=np.float32))
        self.last = -np.inf
        self.frames: list[int] = []
        self.disp: list[np.ndarray] = []
        self.err: list[np.ndarray] = []

    def _image(self, gray: np.ndarray) -> np.ndarray:
        """The flow's image of a working grey frame: the crop, scaled to :attr:`flow_size`."""
        crop = gray[self.y0:self.y1, self.x0:self.x1]
        if crop.shape[1::-1] == self.flow_size:
            return np.ascontiguousarray(crop)
        return cv2.resize(crop, self.flow_size, interpolation=cv2.INTER_AREA)

    def due(self, time_s: float) -> bool:
        """Whether the frame at ``time_s`` seconds gets a flow (the last one is 1 / hz ago)."""
        return self.dis is not None and time_s - self.last >= 1.0 / self.hz - 1e-6

    def compute(self, gray: np.ndarray, time_s: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The grid fields of the working grey ``gray`` of the frame at ``time_s``, or None when
        not :meth:`due`."""
        if not self.due(time_s) or self.dis is None:
            return None
        self.last = time_s
        cur = self._image(gray)
        # both fields averaged onto the grid, then blurred there (STEP px cells, σ = BLUR px in all)
        f = self._grid(self.dis.calc(self.first, cur, None))
        b = self._grid(self.dis.calc(cur, self.first, None))
        back = cv2.remap(b, self.gx + f[..., 0] / STEP, self.gy + f[..., 1] / STEP, cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)
        fb = f + back
        err = cv2.magnitude(fb[..., 0], fb[..., 1])
        return (f / self.fpx).astype(np.float16), err.astype(np.float16)          # frame px; flow px

    def _grid(self, field: np.ndarray) -> np.ndarray:
        """A flow-px field ``(h, w, 2)`` on the grid: cell means, blurred so the whole is ~BLUR px."""
        g = cv2.resize(field, self.grid_size, interpolation=cv2.INTER_AREA)
        return cv2.GaussianBlur(g, (0, 0), GRID_SIGMA)

    def add(self, frame: int, fields: tuple[np.ndarray, np.ndarray] | None) -> None:
        """Keep :meth:`compute`'s result for ``frame`` (index from the first tracked frame)."""
        if fields is not None:
            self.frames.append(int(frame))
            self.disp.append(fields[0])
            self.err.append(fields[1])

    def result(self) -> AnchoredFlow | None:
        """The flows computed so far, or None when there are none (``hz`` 0, or no frame yet)."""
        if not self.frames:
            return None
        # grid sample j averages flow px [STEP·j, STEP·(j+1)): its centre, in frame px
        origin = np.array([self.x0, self.y0]) / self.scale + (STEP - 1) / 2.0 / self.fpx
        return AnchoredFlow(np.asarray(self.frames, np.int64), np.stack(self.disp), np.stack(self.err),
                            origin, STEP / self.fpx)
