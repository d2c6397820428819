"""Branch widths and centre lines measured in frame 1, so the built tree covers what the video shows.

The 2D skeleton's nodes come from tracks and from a trace of the darkest bark, which runs along
the shaded side of a lit branch; the pipe model's radii follow the tip count, not the video. Here:

1. Tree pixels (:func:`tree_map`): frame-1 pixels inside the outline whose colour (CIELAB) is
   farther from every colour of the background (a band just outside the outline) than the
   background's own colours are from each other.
2. Profiles (:func:`measure_branches`): across every skeleton edge, at a few points along it, the
   run of tree pixels through the edge gives the branch's width (px) and its centre's offset
   from the edge (px). An edge's width and offset are medians over its profiles; a profile whose
   run reaches the profile's end (foliage, a blob) says nothing.
3. Radii and centre lines (:func:`fit_to_video`): the pipe model scaled by the trunk's measured
   width, then every branch whose measurement agrees with that within a factor of 1.5 (and is
   not wider than its parent) keeps its own width and pulls its nodes onto its centre line;
   the rest (inside foliage, where two branches cross, across a fork) keep the scaled pipe
   model where they are. The radii then taper from root to tip (:func:`taper`).

Without a clear background (no band outside the outline) or a measurable trunk, the skeleton
and the pipe model stay as they are.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from ..topology import edges_of, topological_order

#: the width of the background band sampled outside the outline, share of the tree's height
BAND = 0.04
#: the least CIELAB distance from the background that counts as the tree (ΔE ≈ 2.3 is barely
#: visible; a clean synthetic sky would otherwise set the threshold at its compression noise)
MIN_CONTRAST = 5.0
#: a run's level is this percentile of its distances (see measure_branches)
LEVEL_PERCENTILE = 75.0
#: profiles along each edge (parameters t along parent → child)
PROFILE_T = (0.3, 0.5, 0.7)
#: branches narrower than this (px) set no scale: anti-aliasing decides their width
MIN_MEASURED_PX = 3.0
#: a branch measured wider than this × its parent's radius is not trusted (see fit_to_video)
PARENT_SLACK = 1.1


@dataclass
class BranchFit:
    """What frame 1 says about the skeleton's branches.

    ``width_px (N,)`` full width of the branch ending at each node (NaN: not measured, and the
    root); ``offset_px (N, 2)`` from that branch's axis to its centre line in the video (0 when
    not measured); ``tree_share`` share of the outline's pixels that look like the tree."""

    width_px: np.ndarray
    offset_px: np.ndarray
    tree_share: float

    @property
    def n_measured(self) -> int:
        return int(np.isfinite(self.width_px).sum())


@dataclass
class TreeMap:
    """Frame 1 against its background: ``dist (H, W)`` float32 CIELAB distance of each pixel inside
    the outline to the nearest background colour (0 outside), ``thr`` the distance above which a
    pixel is the tree, ``floor`` the background's typical distance (its noise), ``share`` the
    share of the outline's pixels that are the tree."""

    dist: np.ndarray
    thr: float
    floor: float
    share: float = 0.0

    @property
    def tree(self) -> np.ndarray:
        """``(H, W)`` bool: the tree's pixels."""
        return self.dist > self.thr

    def level(self) -> np.ndarray:
        """``(H, W)`` float32 in [0, 1], how unlike the background each pixel is:
        ``T = clip((dist − floor) / (2 (thr − floor)), 0, 1)``: 0 at the background's typical
        distance, ½ at the threshold, 1 at twice as far above the floor."""
        span = max(2.0 * (self.thr - self.floor), 1e-3)
        return np.clip((self.dist - self.floor) / span, 0.0, 1.0).astype(np.float32)


def frame_lab(frame_bgr: np.ndarray) -> np.ndarray:
    """``(H, W, 3)`` float32 CIELAB of a BGR uint8 frame, lightly blurred (σ 0.7 px: JPEG/H.264
    noise, not edges), as every colour comparison of frame 1 reads it."""
    return cv2.cvtColor(cv2.GaussianBlur(frame_bgr, (0, 0), 0.7), cv2.COLOR_BGR2LAB).astype(np.float32)


def colour_reference(colours: np.ndarray) -> tuple[cKDTree, np.ndarray]:
    """Split sampled ``colours (S, 3)`` CIELAB into halves: a KD-tree of the first (the
    reference) and each second-half sample's distance to it ``(S − S//2,)``, the reference's own
    spread, from which a threshold "like the reference" is read."""
    ref, held = colours[:len(colours) // 2], colours[len(colours) // 2:]
    kd = cKDTree(ref)
    return kd, kd.query(held)[0]


def background_ring(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns ``(B,)``, ``(B,)`` of the background band just outside the outline ``mask
    (H, W)`` bool: :data:`BAND` of the outline's height wide (at least 3 px); empty for an empty
    mask."""
    ys, _ = np.nonzero(mask)
    if len(ys) == 0:
        return ys, ys
    band_px = max(3, int(round(BAND * float(ys.max() - ys.min() + 1))))
    near = cv2.dilate(mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * band_px + 1,) * 2)) > 0
    by, bx = np.nonzero(near & ~mask)
    return by, bx


def tree_map(frame_bgr: np.ndarray, mask: np.ndarray, seed: int = 0,
             max_samples: int = 4000, lab: np.ndarray | None = None) -> TreeMap | None:
    """Frame 1's pixels against the background in a band just outside the outline ``mask (H, W)``:
    a pixel is the tree when its CIELAB distance to the nearest background sample exceeds the 99th
    percentile of held-out background samples' distances plus 2 units (at least
    ``MIN_CONTRAST``). ``lab`` the frame's :func:`frame_lab` if already computed. None when the
    outline leaves no background band (it fills the frame)."""
    mask = np.asarray(mask, bool)
    h, w = mask.shape
    by, bx = background_ring(mask)
    if len(by) < 50:
        return None
    if lab is None:
        lab = frame_lab(frame_bgr)
    pick = np.random.default_rng(seed).choice(len(by), min(2 * max_samples, len(by)), replace=False)
    kd, d_bg = colour_reference(lab[by[pick], bx[pick]])
    iy, ix = np.nonzero(mask)
    d, _ = kd.query(lab[iy, ix])
    dist = np.zeros((h, w), np.float32)
    dist[iy, ix] = d
    thr = max(float(np.percentile(d_bg, 99)) + 2.0, MIN_CONTRAST)
    return TreeMap(dist, thr, float(np.median(d_bg)), float((d > thr).mean()))


def measure_branches(parents: np.ndarray, nodes_px: np.ndarray, tmap: TreeMap,
                     max_half_px: float | None = None, step: float = 0.5) -> BranchFit:
    """Widths and centre offsets of the skeleton's branches in frame 1 (``tmap``).

    ``parents (N,)``, ``nodes_px (N, 2)`` frame-1 pixels (x, y). Each edge gets profiles at
    ``PROFILE_T`` across it, ``±max_half_px`` long (default 10 % of the skeleton's height, ≥ 8 px),
    sampled every ``step`` px. On each, the run of tree pixels through the edge (or through the
    nearest tree pixel within 2 px), widened by 2 px each side, is cut again where the distance
    crosses half the run's own level (``floor + (level − floor) / 2``, level = the ``LEVEL_PERCENTILE`` of d on the run): blur and
    chroma subsampling spread an edge, its half-contrast crossing stays. Width = the length above
    half, centre = the mean offset of those samples."""
    parents = np.asarray(parents)
    P = np.asarray(nodes_px, np.float64)
    N = len(parents)
    width = np.full(N, np.nan)
    dist = np.asarray(tmap.dist, np.float32)
    share = float(tmap.share)
    e = edges_of(parents)
    if len(e) == 0:
        return BranchFit(width, np.zeros((N, 2)), share)
    if max_half_px is None:
        max_half_px = max(8.0, 0.1 * float(np.ptp(P[:, 1])))
    a, b = P[e[:, 0]], P[e[:, 1]]
    d = b - a
    length = np.linalg.norm(d, axis=1)
    ok_edge = length > 1e-6
    u = d / np.maximum(length, 1e-9)[:, None]
    n = np.stack([-u[:, 1], u[:, 0]], 1)                               # unit normal (E, 2)
    t = np.asarray(PROFILE_T)
    centre = a[:, None] + t[None, :, None] * d[:, None]                # (E, T, 2)
    s = np.arange(-max_half_px, max_half_px + step / 2, step)          # (L,) offsets along the normal
    c = int(np.argmin(np.abs(s)))
    pts = centre[:, :, None, :] + s[None, None, :, None] * n[:, None, None, :]      # (E, T, L, 2)
    L = len(s)
    mx = pts[..., 0].reshape(-1, L).astype(np.float32)
    my = pts[..., 1].reshape(-1, L).astype(np.float32)
    prof_d = cv2.remap(dist, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    prof = prof_d > tmap.thr                                           # (M, L)
    idx = np.arange(L)
    # the run through the centre, or through the nearest tree sample within 2 px
    dist_c = np.where(prof, np.abs(idx - c), L)
    j0 = dist_c.argmin(1)
    found = dist_c[np.arange(len(prof)), j0] * step <= 2.0
    left = np.where(~prof & (idx[None] < j0[:, None]), idx[None], -1).max(1)
    right = np.where(~prof & (idx[None] > j0[:, None]), idx[None], L).min(1)
    closed = (left >= 0) & (right < L)                                 # the run ends inside the profile
    pad = int(round(2.0 / step))
    span = (idx[None] > left[:, None] - pad) & (idx[None] < right[:, None] + pad)
    run = (idx[None] > left[:, None]) & (idx[None] < right[:, None])
    # the half-contrast crossing of the run's own level (bark texture keeps it above half)
    # (a high percentile, not the peak: lit bark is paler than shaded bark, and half the peak
    # would cut it off; not the median either, which the blurred edges pull down on thin branches)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)                # rows without a run: not valid
        level = np.nanpercentile(np.where(run, prof_d, np.nan), LEVEL_PERCENTILE, axis=1)
    level = np.where(np.isfinite(level), level, tmap.thr)
    half = tmap.floor + 0.5 * (level - tmap.floor)
    inner = span & (prof_d > half[:, None])
    area = inner.sum(1).astype(float)
    run_w = area * step
    run_c = (inner * (idx[None] - c)).sum(1) / np.maximum(area, 1e-9) * step
    valid = (found & closed).reshape(len(e), len(t)) & ok_edge[:, None]
    wv = np.where(valid, run_w.reshape(len(e), len(t)), np.nan)
    cv = np.where(valid, run_c.reshape(len(e), len(t)), np.nan)
    enough = valid.sum(1) >= 2
    we = np.full(len(e), np.nan)
    ce = np.full(len(e), np.nan)
    we[enough] = np.nanmedian(wv[enough], axis=1)
    ce[enough] = np.nanmedian(cv[enough], axis=1)
    width[e[:, 1]] = we
    offset = np.zeros((N, 2))
    offset[e[:, 1]] = np.where(np.isfinite(ce), ce, 0.0)[:, None] * n
    return BranchFit(width, offset, share)


@dataclass
class VideoFit:
    """What the fit gives the tree: ``radius_px (N,)`` px (None: keep the pipe model),
    ``shift_px (N, 2)`` node moves onto the centre lines, ``trusted (N,)`` bool, the branches
    (by child node) whose own measured width was kept before tapering."""

    radius_px: np.ndarray | None
    shift_px: np.ndarray
    trusted: np.ndarray


def taper(parents: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``(N,)`` radii that never grow from root to tip: the mean of the lower envelope (each
    radius capped by its parent's, root first) and the upper one (each parent at least as thick
    as its children, tips first). Both envelopes taper, so their mean does; one narrow
    measurement neither thins its whole subtree (as the cap alone would) nor makes a wasp
    waist under a thick branch."""
    parents = np.asarray(parents)
    order = topological_order(parents)
    lo, hi = np.array(r, np.float64), np.array(r, np.float64)
    for n in order[1:]:                                    # root first
        lo[n] = min(lo[n], lo[parents[n]])
    for n in order[::-1][:-1]:                             # tips first
        hi[parents[n]] = max(hi[parents[n]], hi[n])
    return 0.5 * (lo + hi)


def fit_to_video(parents: np.ndarray, level: np.ndarray, nodes_px: np.ndarray, fit: BranchFit,
                 exponent: float = 2.0, trunk_px: float = float("nan")) -> VideoFit:
    """Radii and node moves (:class:`VideoFit`) from the measurements ``fit``.

    The pipe model ``r_pipe`` (tips 1) is scaled by the trunk, whose base is bark in nearly
    every video: ``k = median(width / 2 / r_pipe)`` over the measured trunk edges (level 0) in
    the lower third of the trunk, each at least ``MIN_MEASURED_PX`` wide. A branch's own width
    is trusted when it agrees with ``k · r_pipe`` within [1/2, 3/2] (farther off, the profile
    crossed foliage or a second branch) and, for branches above the trunk, root to tip, is at
    most ``PARENT_SLACK`` × its parent's radius (wider, the profile ran across a fork; the
    trunk's own widths set k and only taper). A trunk width ``trunk_px`` the trace measured
    (:attr:`.skeleton2d.Skeleton2D.trunk_width_px`: a sunlit trunk, its colour counted over the
    outline's stem, where the profiles see grooved bark against wood around the outline's foot)
    sets ``k = trunk_px / 2 / r_pipe(root)`` instead. Trusted branches keep their width
    and move their two nodes (a node by the mean offset of its trusted edges) onto the centre
    line; the others keep ``k · r_pipe``. Last, the radii :func:`taper`."""
    from ..tree3d import pipe_radii
    parents = np.asarray(parents)
    N = len(parents)
    shift = np.zeros((N, 2))
    half = 0.5 * np.asarray(fit.width_px, np.float64)
    pipe = pipe_radii(parents, 1.0, exponent).astype(np.float64)
    y = np.asarray(nodes_px, np.float64)[:, 1]
    trunk = np.flatnonzero((np.asarray(level) == 0) & (parents >= 0))
    none = VideoFit(None, shift, np.zeros(N, bool))
    if np.isfinite(trunk_px) and trunk_px >= MIN_MEASURED_PX:
        k = 0.5 * float(trunk_px) / float(pipe[0])
    else:
        if len(trunk) == 0:
            return none
        low = trunk[np.argsort(-y[trunk])][:max(1, int(np.ceil(len(trunk) / 3)))]      # image y grows down
        low = low[np.isfinite(half[low]) & (2 * half[low] >= MIN_MEASURED_PX)]
        if len(low) == 0:
            return none
        k = float(np.median(half[low] / pipe[low]))
    r = k * pipe
    ratio = np.where(np.isfinite(half), half / np.maximum(r, 1e-9), np.nan)
    trusted = np.isfinite(ratio) & (ratio >= 0.5) & (ratio <= 1.5)
    r[trusted] = half[trusted]
    lev = np.asarray(level)
    for n in topological_order(parents)[1:]:               # root first: parents are final
        if trusted[n] and lev[n] > 0 and half[n] > PARENT_SLACK * r[parents[n]]:
            trusted[n] = False
            r[n] = k * pipe[n]
    e = edges_of(parents)
    te = e[trusted[e[:, 1]]]
    acc = np.zeros((N, 2))
    num = np.zeros(N)
    for col in (0, 1):
        np.add.at(acc, te[:, col], fit.offset_px[te[:, 1]])
        np.add.at(num, te[:, col], 1.0)
    shift = np.where(num[:, None] > 0, acc / np.maximum(num, 1)[:, None], 0.0)
    return VideoFit(taper(parents, r).astype(np.float32), shift, trusted)
