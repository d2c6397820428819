"""What frame 1 alone says about where the branches are, for the trace (working resolution).

The clip's bark statistics (:mod:`.appearance`: dark in most frames, steady) blur a branch that
sways by more than its own width, so a thin limb high in a bare crown leaves no ridge there.
Frame 1 shows it sharp, and the skeleton is traced in frame 1's coordinates. Here:

1. Tree level ``T`` (:meth:`.branch_fit.TreeMap.level`): 0 on the background's colours, 1 on
   colours clearly unlike the background (the band just outside the outline).
2. Bark colour: the trunk's colours in frame 1 (CIELAB), from the pixels of the trunk the clip's
   bark evidence found. When those are no trunk (a sunlit trunk is bright, and the dark pixels
   of the outline's foot are shaded foliage or young trees: their colour marks much of the
   outline, or little of the stem) and the outline narrows to a stem at its foot
   (:func:`stem_core`), from the middle half of the stem's rows, whatever their shade. A pixel
   is bark-coloured when its distance to the nearest trunk sample is at most the trunk's own
   spread (95th percentile of held-out trunk samples) + ``tol``.
3. ``bark = T · [bark-coloured]``, only when at most ``max_share`` of the outline is
   bark-coloured: where leaves are as dark as the bark (conifers, shaded crowns) colour tells
   nothing, and the clip's statistics stay the only bark evidence.
4. ``background = blur(1 − T)``: what frame 1 shows as background, costly to trace through.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .branch_fit import colour_reference, frame_lab, tree_map

#: trunk samples below this count say nothing about the bark's colour
MIN_TRUNK_SAMPLES = 20
#: the stem: rows of the outline's lowest STEM_ROWS of its height at most STEM_NARROW × its
#: widest row wide, of at least MIN_STEM_ROWS rows
STEM_ROWS, STEM_NARROW, MIN_STEM_ROWS = 0.25, 0.35, 5
#: a bark colour that marks less of the stem's middle than this is not the trunk's
MIN_STEM_COVER = 0.5


@dataclass
class FrameEvidence:
    """``bark (h, w)`` float32 in [0, 1] (None: colour does not separate bark from the crown),
    ``background (h, w)`` float32 in [0, 1], ``bark_share`` share of the outline's pixels
    coloured like the trunk (NaN without trunk samples); where the outline narrows to a stem,
    ``stem (h, w)`` bool its middle (:func:`stem_core`) and ``trunk_width`` the median count of
    bark-coloured pixels in its rows (px)."""

    bark: np.ndarray | None
    background: np.ndarray
    bark_share: float
    trunk_width: float = float("nan")
    stem: np.ndarray | None = None


def stem_core(mask: np.ndarray) -> np.ndarray | None:
    """``(h, w)`` bool: the middle half of each row of the outline's stem, the rows of its lowest
    :data:`STEM_ROWS` of the height no wider than :data:`STEM_NARROW` × its widest row (an outline
    drawn round a tree narrows to its trunk at the foot); None without such a stem (a crown to the
    ground, an outline drawn as a box)."""
    ys, _ = np.nonzero(mask)
    if not len(ys):
        return None
    top, bot = int(ys.min()), int(ys.max())
    width = mask.sum(1)
    rows = np.arange(mask.shape[0])
    stem = (rows > bot - STEM_ROWS * (bot - top + 1)) & (width > 0) & (width <= STEM_NARROW * width.max())
    if stem.sum() < MIN_STEM_ROWS:
        return None
    left = mask.argmax(1)
    right = mask.shape[1] - 1 - mask[:, ::-1].argmax(1)
    mid = 0.5 * (left + right)
    cols = np.arange(mask.shape[1])[None]
    return stem[:, None] & mask & (np.abs(cols - mid[:, None]) <= 0.25 * width[:, None])


def bark_coloured(lab: np.ndarray, trunk: np.ndarray, inside: np.ndarray, tol: float,
                  seed: int = 0, max_samples: int = 4000) -> np.ndarray | None:
    """``(h, w)`` bool: pixels of ``inside`` whose CIELAB colour (``lab (h, w, 3)`` float32) is
    within the trunk's own colour spread + ``tol`` of the nearest pixel of ``trunk (h, w)`` bool;
    None with fewer than ``MIN_TRUNK_SAMPLES`` trunk pixels."""
    ty, tx = np.nonzero(trunk)
    if len(ty) < MIN_TRUNK_SAMPLES:
        return None
    pick = np.random.default_rng(seed).permutation(len(ty))[:2 * max_samples]
    kd, d_held = colour_reference(lab[ty[pick], tx[pick]])
    spread = float(np.percentile(d_held, 95))
    iy, ix = np.nonzero(inside)
    out = np.zeros(inside.shape, bool)
    out[iy, ix] = kd.query(lab[iy, ix])[0] <= spread + tol
    return out


def frame_evidence(first_bgr: np.ndarray, mask: np.ndarray, trunk: np.ndarray, tol: float = 2.0,
                   max_share: float = 0.3, seed: int = 0) -> FrameEvidence | None:
    """Frame-1 evidence (module docstring) on ``first_bgr (h, w, 3)`` uint8 inside ``mask (h, w)``,
    bark colour from the ``trunk (h, w)`` bool pixels, or from the outline's stem
    (:func:`stem_core`) when their colour marks more than ``max_share`` of the outline or less
    than :data:`MIN_STEM_COVER` of the stem's middle and the stem's own colour marks at most
    ``max_share``; None when the outline leaves no background band to compare with."""
    lab = frame_lab(first_bgr)
    tm = tree_map(first_bgr, mask, seed, lab=lab)
    if tm is None:
        return None
    level = tm.level()
    background = cv2.GaussianBlur(1.0 - level, (0, 0), 1.0)
    background[~mask] = 1.0
    coloured = bark_coloured(lab, trunk & mask, mask, tol, seed)
    share = float(coloured[mask].mean()) if coloured is not None else np.inf
    stem = stem_core(mask)
    # the clip's trunk pixels tell the bark when their colour marks at most max_share of the
    # outline and at least half the stem's middle (a sunlit trunk is bright: its dark pixels may
    # be shaded foliage or young trees at its foot)
    told = coloured is not None and share <= max_share and (stem is None or coloured[stem].mean() >= MIN_STEM_COVER)
    if stem is not None and not told:
        by_stem = bark_coloured(lab, stem & tm.tree, mask, tol, seed)
        if by_stem is not None and float(by_stem[mask].mean()) <= max_share:
            coloured, share = by_stem, float(by_stem[mask].mean())
    if coloured is None:
        return FrameEvidence(None, background, float("nan"))
    bark = (level * coloured).astype(np.float32) if share <= max_share else None
    width = float("nan") if stem is None else float(np.median((coloured & mask)[stem.any(1)].sum(1)))
    return FrameEvidence(bark, background, share, width, stem)
