"""Which form a tree in a video has (:mod:`..forms`), from frame 1's outline: a conifer's crown
is widest low down and narrows steadily to its top; a palm stands on a long bare trunk under a
crown of fronds that also hang below where they start; anything else is a broadleaf.
"""
from __future__ import annotations

import numpy as np

#: a conifer: its widest rows below this share of its height ...
CONIFER_WIDEST = 0.45
#: ... and its width falling with height above the trunk (Spearman ρ of width against height)
CONIFER_RHO = -0.5


def width_profile(mask: np.ndarray) -> np.ndarray:
    """``(H,)`` pixels of ``mask (h, w)`` bool per row from its lowest row (index 0) to its top."""
    rows = np.flatnonzero(mask.any(1))
    if len(rows) == 0:
        return np.zeros(0)
    return mask[rows.min():rows.max() + 1].sum(1).astype(np.float64)[::-1]


def _spearman(a: np.ndarray, b: np.ndarray) -> float:
    ra, rb = np.argsort(np.argsort(a)), np.argsort(np.argsort(b))
    if np.ptp(ra) == 0 or np.ptp(rb) == 0:
        return 0.0
    return float(np.corrcoef(ra, rb)[0, 1])


def detect_form(outline: np.ndarray) -> tuple[str, str]:
    """``(form, why)``: ``"conifer"`` when the outline ``(h, w)`` bool is widest in its lower
    :data:`CONIFER_WIDEST` of its height and narrows steadily upward above the trunk (Spearman ρ
    of width against height below :data:`CONIFER_RHO`), else ``"broadleaf"``; ``why`` gives the
    numbers. (A palm is not told from a broadleaf by its outline alone: choose it.)"""
    w = width_profile(np.asarray(outline, bool))
    if len(w) < 10:
        return "broadleaf", "the outline is too small to tell a form"
    h = np.arange(len(w)) / (len(w) - 1)
    widest = float(np.median(h[w >= 0.9 * w.max()]))
    stem = int(np.argmax(w > 0.2 * w.max()))                      # rows of the trunk below the crown
    rho = _spearman(h[stem:], w[stem:]) if len(w) - stem >= 5 else 0.0
    why = f"widest at {widest:.0%} of the height, width against height ρ {rho:+.2f}"
    if widest <= CONIFER_WIDEST and rho <= CONIFER_RHO:
        return "conifer", f"a crown that narrows to its top ({why})"
    return "broadleaf", why
