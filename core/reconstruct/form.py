"""Which form a tree in a video has (:mod:`..forms`), from frame 1's outline: a conifer's crown
is widest low down and narrows steadily to its top; a palm stands on a long bare trunk under a
crown of fronds that also hang below where they start; anything else is a broadleaf.
"""
from __future__ import annotations

import cv2
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


#: σ (px at the coherence's scale) of the structure tensor's smoothing
COHERENCE_SIGMA = 3.0
#: the largest side frame 1 is measured at
COHERENCE_SIDE = 640
#: a crown whose texture coherence (median over its foreground) reaches this is long straight
#: strokes (measured: leafy crowns, synthetic and real, 0.23–0.38; palms 0.58–0.64, the real palm
#: from below 0.61; bare crowns of thin branches 0.84–0.91): a palm's fronds or bare branches
STROKES = 0.48


def texture_coherence(frame_bgr: np.ndarray, tree_px: np.ndarray) -> float:
    """The median over ``tree_px (H, W)`` bool of frame 1's structure-tensor coherence
    ``(λ1 − λ2) / (λ1 + λ2)`` (Sobel gradients, tensor smoothed with σ :data:`COHERENCE_SIGMA` px at
    most :data:`COHERENCE_SIDE` px a side): ~0.25 on a crown of leaves (texture with no direction),
    ~0.6 on a palm's leaflets (long parallel strokes). NaN without tree pixels."""
    g = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)
    m = np.asarray(tree_px, bool)
    s = min(1.0, COHERENCE_SIDE / max(g.shape))
    if s < 1.0:
        g = cv2.resize(g, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
        m = cv2.resize(m.astype(np.uint8), (g.shape[1], g.shape[0]), interpolation=cv2.INTER_NEAREST) > 0
    if not m.any():
        return float("nan")
    ix, iy = cv2.Sobel(g, cv2.CV_32F, 1, 0), cv2.Sobel(g, cv2.CV_32F, 0, 1)
    jxx = cv2.GaussianBlur(ix * ix, (0, 0), COHERENCE_SIGMA)
    jyy = cv2.GaussianBlur(iy * iy, (0, 0), COHERENCE_SIGMA)
    jxy = cv2.GaussianBlur(ix * iy, (0, 0), COHERENCE_SIGMA)
    coherence = np.sqrt((jxx - jyy) ** 2 + 4 * jxy ** 2) / np.maximum(jxx + jyy, 1e-6)
    return float(np.median(coherence[m]))


def palm_hint(frame_bgr: np.ndarray | None, tree_px: np.ndarray | None) -> str | None:
    """A suggestion to choose *Palm* when frame 1's crown is long straight strokes
    (:func:`texture_coherence` ≥ :data:`STROKES`), or None. Only a suggestion: a bare crown's
    branches are strokes too, and the outline cannot tell them apart (its cues were measured
    in issue 19; neither separated palms from broadleaf samples)."""
    if frame_bgr is None or tree_px is None:
        return None
    c = texture_coherence(frame_bgr, tree_px)
    if not c >= STROKES:
        return None
    return (f"the crown is long straight strokes (texture coherence {c:.2f}; leafy crowns measure "
            f"0.23-0.38): a palm's fronds or bare branches; if it is a palm, choose Form: Palm")


#: how often a form read from an outline found on a photo (``--outline auto``) was right, as
#: (right, read) on the 48 labelled real photos of ``benchmarks/real_photo_forms.py`` (35 outlined):
#: a found outline takes in the shrubs and trees round a tree's foot, which widen any crown low
#: down, so broadleaves read as conifers about as often as conifers do (the width profiles of the
#: two overlap, and so did the apex's taper, texture coherence, lightness and saturation measured
#: on the same photos: no cue of the outline or the crown's pixels told them apart)
FOUND_PHOTO_RIGHT = {"conifer": (6, 18), "broadleaf": (11, 17)}


def found_outline_note(form: str, why: str) -> str:
    """The warning a form read from an outline found on a photo carries: the reading, what it is
    worth on real photos (:data:`FOUND_PHOTO_RIGHT`), and the choice that settles it."""
    right, read = FOUND_PHOTO_RIGHT.get(form, (0, 0))
    other = "Broadleaf" if form == "conifer" else "Conifer"
    return (f"the form ({form}: {why}) was read from the outline found on the photo, and such readings "
            f"were right for {right} of {read} real photos (a found outline takes in what stands round the "
            f"tree's foot); if the tree is not a {form}, choose Form: {other}")
