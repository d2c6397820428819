"""The tree in one photo (issue 35): its outline found (``--outline auto`` on a photo,
:func:`photo_outline`), and a drawn outline checked to hold a tree (:func:`check_tree_inside`).

A photo has no motion to tell the tree from its background (:mod:`.auto_outline` finds what
sways), so here the tree is what does not look like the picture's border: a graph cut
(``cv2.grabCut``) seeded with a strip round the border as background and everything else as
probably tree learns two colour mixtures, and the sky, the ground at the foot of the frame and
trees beside it fall to the background's. What the cut keeps that is not the tree:

* **the ground**: a band across the bottom of the frame that touches both sides (grass, a fence,
  a house) joined to the tree by its trunk. It is cut off where the tree above it narrows to a
  trunk (:func:`ground_line`), and the trunk is followed down into it by colour, pixel by pixel
  against the band's own colours (:func:`trunk_foot`);
* **other things**: only the largest region is kept.

The region is closed over the sky seen through the crown and widened a little, as a hand-drawn
outline is, so the foreground cut inside it (:mod:`.foreground`) has a clean ring of background
round it. Measured against the samples' drawn outlines (frame 1 of the held-out seeds of ten
variants, ``tests/test_photo_outline.py``) and the real photos' (``benchmarks/real_photos.py``).

It needs a tree that stands clear of its background: against the sky, or other trees of another
colour. A photo taken inside a wood, of a branch, or of a tree merged with others gives a region
too small or too odd for a tree, and :func:`photo_outline` says so in one line (draw the outline
instead). No bpy.
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from ..outline import Outline, largest_component, polygon_to_mask
from .foreground import local_texture

#: the cut works on the photo scaled so its larger side is at most this many px (0.4–1.8 s a real
#: photo on 2 cores)
SIDE = 320
#: the border strip taken as background, a share of the shorter side
BORDER = 0.03
#: grabCut's iterations
ITERATIONS = 5
#: grey levels: below this standard deviation over 7 × 7 px of the scaled photo a pixel starts as
#: probably background (clear sky; a crown's leaves measure 15–40)
SMOOTH = 6.0
#: a row is ground when the cut keeps at least this share of it and reaches both sides ...
GROUND_COVER = 0.5
#: ... within the lower half of the frame, and it is cut off only under a trunk: the tree's
#: pixels on the rows just above it at most this share of its crown's widest span
NECK = 0.35
#: colour samples each side of the trunk-or-ground test (nearest sample decides)
FOOT_SAMPLES = 400
#: the outline closes gaps up to this share of the tree's height (sky through the crown) ...
CLOSE = 0.06
#: ... and stands this share of the height off the tree
MARGIN = 0.02
#: a tree is textured (foliage, branches against the sky): at least this share of an outline's
#: pixels measure :func:`.foreground.local_texture` ≥ :data:`TREE_TEXTURE` (measured: the samples'
#: frame 1 0.31–0.93, a backlit crown least; the real photos 0.95; sky over grass 0.017, a wall
#: with noise of σ 2–8 grey levels 0.000–0.002)
TREE_TEXTURED = 0.05
TREE_TEXTURE = 2.0
#: the smallest tree found: this share of the photo's height, and of its area
MIN_HEIGHT = 0.25
MIN_AREA = 0.03
#: why no tree is found, as measured on real photos (``benchmarks/real_photo_forms.py``: all 13
#: of the 48 whole-tree photos that found none had a crown running off the picture's top or sides,
#: or trees of the crown's colours filling the picture behind it; cut again with the top and
#: sides only probably background, they gave the whole picture above the ground, and trees with
#: square crowns), and what to do
RUNS_OFF = "a crown running off the picture's top or sides, or other trees of its colours behind it?"
WHOLE_TREE = ("use a photo with the whole tree in view against the sky or the ground, or draw the tree's outline "
              "and give --outline OUTLINE.json")


def tree_cut(bgr: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``(small (h, w, 3) uint8, kept (h, w) bool, scale)``: the photo scaled to :data:`SIDE` px
    and what the graph cut keeps as not-background there; ``scale`` small px per photo px."""
    h, w = bgr.shape[:2]
    s = min(1.0, SIDE / max(h, w))
    small = cv2.resize(bgr, None, fx=s, fy=s, interpolation=cv2.INTER_AREA) if s < 1.0 else bgr.copy()
    hh, ww = small.shape[:2]
    seeds = np.full((hh, ww), cv2.GC_PR_FGD, np.uint8)
    b = max(2, int(round(BORDER * min(hh, ww))))
    seeds[:b] = seeds[-b:] = cv2.GC_BGD
    seeds[:, :b] = seeds[:, -b:] = cv2.GC_BGD
    grey = cv2.cvtColor(small, cv2.COLOR_BGR2GRAY).astype(np.float32)
    mean = cv2.blur(grey, (7, 7))
    smooth = np.sqrt(np.maximum(cv2.blur(grey * grey, (7, 7)) - mean * mean, 0)) < SMOOTH
    seeds[(seeds == cv2.GC_PR_FGD) & smooth] = cv2.GC_PR_BGD        # sky: no texture (a start, not a verdict)
    cv2.setRNGSeed(0)                                   # its k-means start: the same outline every run
    cv2.grabCut(small, seeds, None, np.zeros((1, 65)), np.zeros((1, 65)), ITERATIONS, cv2.GC_INIT_WITH_MASK)
    return small, (seeds == cv2.GC_FGD) | (seeds == cv2.GC_PR_FGD), s


def ground_line(kept: np.ndarray) -> int:
    """The row (px from the top) where the ground under the tree begins in ``kept (h, w)`` bool,
    or ``h`` when the tree does not stand on a band of ground the cut kept.

    Ground rows: in the lower half, at least :data:`GROUND_COVER` of the row kept, reaching both
    sides (within three border strips). The top of a run of them is the ground line when the
    largest region above it is a trunk there: its pixels on the three rows above at most
    :data:`NECK` of the region's widest span (a crown that reaches the ground, or trees across
    the frame, are not cut)."""
    hh, ww = kept.shape
    b = max(2, int(round(BORDER * min(hh, ww))))
    inner = kept[:, b:ww - b]
    cover = inner.mean(1)
    e = 3 * b
    rows = (cover >= GROUND_COVER) & inner[:, :e].any(1) & inner[:, -e:].any(1)
    rows[: hh // 2] = False
    rows = np.convolve(rows.astype(np.float64), np.ones(5) / 5, "same") >= 0.6   # no single stray rows
    for g in np.flatnonzero(rows & ~np.r_[False, rows[:-1]]):                      # each run's top
        if g < 3:
            continue
        above = kept.copy()
        above[g:] = False
        tree = largest_component(above)
        if not tree.any():
            continue
        span = np.where(tree.any(1), ww - np.argmax(tree[:, ::-1], 1) - np.argmax(tree, 1), 0)
        if tree[g - 3:g].sum(1).mean() <= NECK * span.max():
            return int(g)
    return hh


def trunk_foot(small: np.ndarray, tree: np.ndarray, g: int) -> np.ndarray:
    """``tree (h, w)`` bool with its trunk followed below the ground line ``g``: the band's pixels
    near the trunk (within its width either side) whose colour (CIELAB) is nearer the tree's just
    above the line than the band's own away from the trunk, joined to the tree."""
    hh, ww = tree.shape
    if g >= hh or not tree[g - 1].any():
        return tree
    lab = cv2.cvtColor(small, cv2.COLOR_BGR2LAB).astype(np.float32)
    top = lab[max(0, g - 6):g][tree[max(0, g - 6):g]]
    band = lab[g:]
    cols = np.flatnonzero(tree[g - 1])
    x0, x1 = int(cols.min()), int(cols.max()) + 1
    near = np.zeros(band.shape[:2], bool)
    near[:, max(0, 2 * x0 - x1):x1 + (x1 - x0)] = True
    ground = band[~near]
    if len(ground) == 0 or len(top) == 0:
        return tree
    rng = np.random.default_rng(0)

    def pick(a: np.ndarray) -> np.ndarray:
        return a[rng.choice(len(a), min(FOOT_SAMPLES, len(a)), replace=False)]

    flat = band.reshape(-1, 3)
    d_tree = cKDTree(pick(top)).query(flat)[0].reshape(near.shape)
    d_ground = cKDTree(pick(ground)).query(flat)[0].reshape(near.shape)
    joined = tree.copy()
    joined[g:] = (d_tree < d_ground) & near
    _, lab_ids = cv2.connectedComponents(joined.astype(np.uint8), connectivity=8)
    keep = np.unique(lab_ids[tree])
    return np.isin(lab_ids, keep[keep > 0])


def photo_outline(bgr: np.ndarray, where: str = "the photo") -> Outline:
    """The outline (polygon and mask in px of ``bgr``) of the tree in the photo ``bgr (H, W, 3)``
    uint8. Raises :class:`InputError` when no region the size of a tree (:data:`MIN_HEIGHT` of
    the photo's height, :data:`MIN_AREA` of its area) stands clear of the background."""
    H, W = bgr.shape[:2]
    small, kept, s = tree_cut(bgr)
    hh, ww = kept.shape
    g = ground_line(kept)
    above = kept.copy()
    above[g:] = False
    tree = largest_component(above)
    if not tree.any():
        raise InputError(f"could not find a tree standing clear of the background in {where}: nothing in it differs "
                         f"from its border ({RUNS_OFF}); {WHOLE_TREE}")
    tree = trunk_foot(small, tree, g)
    rows = np.flatnonzero(tree.any(1))
    height = float(np.ptp(rows) + 1)
    r = max(2, int(CLOSE * height))
    closed = cv2.morphologyEx(np.pad(tree, r).astype(np.uint8), cv2.MORPH_CLOSE,
                              cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))[r:-r, r:-r]
    d = max(1, int(MARGIN * height))
    closed = cv2.dilate(closed, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * d + 1,) * 2))
    if height < MIN_HEIGHT * hh or closed.sum() < MIN_AREA * hh * ww:
        raise InputError(f"could not find a tree standing clear of the background in {where} (the largest region is "
                         f"{height / hh:.0%} of its height, {closed.sum() / (hh * ww):.1%} of its area: {RUNS_OFF}); "
                         f"{WHOLE_TREE}")
    contours, _ = cv2.findContours(closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    contour = max(contours, key=cv2.contourArea)
    poly = cv2.approxPolyDP(contour, 0.005 * cv2.arcLength(contour, True), True).reshape(-1, 2).astype(np.float64)
    poly = np.clip((poly + 0.5) / s - 0.5, 0, [W - 1, H - 1])
    return Outline(poly.astype(np.float32), polygon_to_mask(poly, W, H))


def textured_share(bgr: np.ndarray, mask: np.ndarray) -> float:
    """The share of ``mask (H, W)`` bool's pixels of the photo ``bgr`` whose local texture
    (:func:`.foreground.local_texture`, at most 640 px a side) is at least :data:`TREE_TEXTURE`."""
    s = min(1.0, 640 / max(bgr.shape[:2]))
    m = np.asarray(mask, bool)
    if s < 1.0:
        bgr = cv2.resize(bgr, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
        m = cv2.resize(m.astype(np.uint8), (bgr.shape[1], bgr.shape[0]), interpolation=cv2.INTER_NEAREST) > 0
    if not m.any():
        return 0.0
    texture = local_texture(cv2.cvtColor(bgr, cv2.COLOR_BGR2LAB)[..., 0].astype(np.float32) * (100.0 / 255.0))
    return float((texture[m] >= TREE_TEXTURE).mean())


def check_tree_inside(bgr: np.ndarray, mask: np.ndarray, where: str = "the photo") -> None:
    """:class:`InputError` when the outline ``mask (H, W)`` bool holds nothing a tree's texture
    (:func:`textured_share` under :data:`TREE_TEXTURED`: sky, a wall), naming the share."""
    share = textured_share(bgr, mask)
    if share < TREE_TEXTURED:
        raise InputError(f"no tree inside the outline in {where}: only {share:.1%} of it has a crown's or a "
                         f"branch's texture (a tree: {TREE_TEXTURED:.0%} or more); draw the outline round the tree")
