"""What frame 1 alone says about where the branches are, for the trace (working resolution).

The clip's bark statistics (:mod:`.appearance`: dark in most frames, steady) blur a branch that
sways by more than its own width, so a thin limb high in a bare crown leaves no ridge there.
Frame 1 shows it sharp, and the skeleton is traced in frame 1's coordinates. Here:

1. Tree level ``T`` (:meth:`.branch_fit.TreeMap.level`): 0 on the background's colours, 1 on
   colours clearly unlike the background (the band just outside the outline).
2. Bark colour: the trunk's colours in frame 1 (CIELAB, pixels of the trunk the clip's bark
   evidence found). A pixel is bark-coloured when its distance to the nearest trunk sample is
   at most the trunk's own spread (95th percentile of held-out trunk samples) + ``tol``.
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


@dataclass
class FrameEvidence:
    """``bark (h, w)`` float32 in [0, 1] (None: colour does not separate bark from the crown),
    ``background (h, w)`` float32 in [0, 1], ``bark_share`` share of the outline's pixels
    coloured like the trunk (NaN without trunk samples)."""

    bark: np.ndarray | None
    background: np.ndarray
    bark_share: float


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
    bark colour from the ``trunk (h, w)`` bool pixels; None when the outline leaves no background
    band to compare with."""
    lab = frame_lab(first_bgr)
    tm = tree_map(first_bgr, mask, seed, lab=lab)
    if tm is None:
        return None
    level = tm.level()
    background = cv2.GaussianBlur(1.0 - level, (0, 0), 1.0)
    background[~mask] = 1.0
    coloured = bark_coloured(lab, trunk & mask, mask, tol, seed)
    if coloured is None:
        return FrameEvidence(None, background, float("nan"))
    share = float(coloured[mask].mean())
    bark = (level * coloured).astype(np.float32) if share <= max_share else None
    return FrameEvidence(bark, background, share)
