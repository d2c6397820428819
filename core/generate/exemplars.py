"""Tree exemplars as fixed-length contours (issue 36 part 2; seed 000 §4, "tree variations from RGBA
exemplars"): an RGBA picture of a tree → its crown and trunk, its longest outer contour resampled to
:data:`N_POINTS` points between three pins, and a simplified contour for the colour transfer.

1. **Normalize** (§4.1): the opaque pixels (alpha ≥ 0.5) cropped to their box, padded square with a
   transparent margin of :data:`MARGIN` and resized to ``size`` px; colour resized premultiplied by
   alpha, so the transparent pixels' colour does not bleed into the tree's edge.
2. **Crown and trunk** (§4.3, without the seed's network): from the alpha's row profile. The trunk
   is the bottom run of rows at most :data:`TRUNK_WIDTH` × the bottom rows' median width wide
   (and at most :data:`TRUNK_SHARE` of the tree's width); the crown baseline is the lowest row wider
   than that. A trunk shorter than :data:`MIN_TRUNK` of the height counts as none (L = R = B, as the
   seed does for a hidden trunk).
3. **Contour** (§4.2): the longest external contour of the alpha mask (border following), oriented
   so that from the tree's bottom it runs up the right side, over the crown and down the left.
4. **Pins** (§4.4): B the bottom point (the median of the lowest ones); R and L the first points from
   B, forward and backward, at or above the crown baseline.
5. **Resampling** (§4.5): B→R, R→L and L→B each resampled at uniform chord length to
   :data:`TRUNK_POINTS`, :data:`CROWN_POINTS` and :data:`TRUNK_POINTS` points (the seed's 200 /
   1,600 / 200 of 2,000), so index k of every exemplar's contour is the same place on a tree.
6. **Simplified contour** (§4.6): every :data:`SIMPLE_STEP`-th point of the resampled contour after a
   circular moving average of the same width, pushed outward by :data:`DILATE` of the side (the
   seed dilates the mask 8 px of 1,024 before taking its contour; an offset keeps the points in
   correspondence across exemplars, which a new contour of the dilated mask would not).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import InputError

#: the normalized exemplar's side, px (the seed's 1,024; the transfer's cost goes with its square)
SIZE = 512
#: transparent margin around the tree in the normalized square, share of its side
MARGIN = 0.04
#: alpha at or above this is the tree (the seed's 0.5)
ALPHA_T = 128
#: contour points: B→R and L→B (each) and R→L (seed: 200, 200, 1,600 of 2,000)
TRUNK_POINTS = 200
CROWN_POINTS = 1600
N_POINTS = 2 * TRUNK_POINTS + CROWN_POINTS
#: every this-many resampled points make the simplified contour (2,000 / 20 = the seed's 100)
SIMPLE_STEP = 20
#: the simplified contour's outward offset, share of the side (seed: 8 px dilation at 1,024)
DILATE = 8 / 1024
#: a row is trunk while at most this many times the bottom rows' median width ...
TRUNK_WIDTH = 2.5
#: ... and at most this share of the tree's width
TRUNK_SHARE = 0.3
#: the bottom rows the trunk's width is measured on, share of the height
BOTTOM = 0.03
#: a trunk shorter than this share of the height is none
MIN_TRUNK = 0.03


@dataclass
class Exemplar:
    """A normalized exemplar: ``rgba (S, S, 4)`` uint8 (straight alpha), ``trunk (S, S)`` bool its
    trunk's pixels, ``contour (N_POINTS, 2)`` px (x right, y down; index 0 = B, ``TRUNK_POINTS`` =
    R, ``TRUNK_POINTS + CROWN_POINTS`` = L), ``simple (N_POINTS // SIMPLE_STEP, 2)`` px, ``baseline``
    the crown's lowest row (px, = the bottom row without a trunk), ``name`` where it came from."""

    rgba: np.ndarray
    trunk: np.ndarray
    contour: np.ndarray
    simple: np.ndarray
    baseline: int
    name: str = ""

    @property
    def size(self) -> int:
        return int(self.rgba.shape[0])

    @property
    def has_trunk(self) -> bool:
        return bool(self.trunk.any())

    def mirrored(self) -> "Exemplar":
        """The same tree seen from behind (left and right swapped), its contour re-pinned."""
        return exemplar_from_rgba(self.rgba[:, ::-1].copy(), self.name + " (mirrored)", self.size)


def read_exemplar(path: str | os.PathLike, size: int = SIZE, outline: str | os.PathLike | None = None) -> Exemplar:
    """The exemplar in the RGBA image ``path``, or in the photo ``path`` cut out by ``outline`` (a
    polygon .json or a mask image, as a video's: :func:`photo_cutout`); :class:`InputError` (one
    line) when it is not one."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"exemplar '{path}' does not exist; give an RGBA image of a tree (PNG with transparency)")
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise InputError(f"exemplar '{path}' cannot be read as an image; give an RGBA PNG of a tree")
    if img.dtype != np.uint8:                       # 16-bit PNG/TIFF: to 8 bits once, for either kind
        img = (img.astype(np.float64) * (255.0 / np.iinfo(img.dtype).max)).round().astype(np.uint8)
    if outline is not None:
        bgr = img[..., :3] if img.ndim == 3 else cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        rgba = photo_cutout(bgr, outline, where=f"exemplar '{path}'")
        return exemplar_from_rgba(rgba, os.path.basename(path), size, where=f"exemplar '{path}'")
    if img.ndim != 3 or img.shape[2] != 4:
        raise InputError(f"exemplar '{path}' has no alpha channel; give an RGBA image of a tree (transparent "
                         "around it), e.g. a billboard.png the project wrote")
    rgba = cv2.cvtColor(img, cv2.COLOR_BGRA2RGBA)
    return exemplar_from_rgba(rgba, os.path.basename(path), size, where=f"exemplar '{path}'")


def photo_cutout(bgr: np.ndarray, outline: str | os.PathLike, where: str = "the photo") -> np.ndarray:
    """``(H, W, 4)`` RGBA uint8 of a photo of a tree: alpha the outline's pixels that are the tree
    against the sky and ground around it (the trace's own test: CIELAB distance to the background
    ring just outside the outline, :func:`..reconstruct.branch_fit.tree_map`), soft: its level, ½ at
    the trace's threshold; the whole outline when it leaves no background around it."""
    from ..outline import load_outline
    from ..reconstruct.branch_fit import tree_map
    h, w = bgr.shape[:2]
    mask = load_outline(os.fspath(outline), w, h).mask.astype(bool)
    if not mask.any():
        raise InputError(f"the outline of {where} holds no pixel of it; draw it around the tree in the photo")
    tmap = tree_map(bgr, mask)
    if tmap is None:
        alpha = mask.astype(np.float32)
    else:                          # soft: ½ at the trace's threshold, so a sky-tinted edge fades out
        alpha = np.where(mask, tmap.level(), 0.0).astype(np.float32)
    return np.dstack([cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), np.round(alpha * 255).astype(np.uint8)])


def exemplar_from_rgba(rgba: np.ndarray, name: str = "", size: int = SIZE, where: str = "the exemplar") -> Exemplar:
    """The :class:`Exemplar` of an RGBA uint8 picture ``(H, W, 4)`` (module docstring, steps 1–6)."""
    opaque = rgba[..., 3] >= ALPHA_T
    if opaque.sum() < 64:
        raise InputError(f"{where} is transparent (no tree in its alpha); give an RGBA image of a tree")
    if opaque.all():
        raise InputError(f"{where} has no transparent pixels; give an RGBA image whose alpha is 0 around the tree")
    norm = normalize(rgba, size)
    mask = norm[..., 3] >= ALPHA_T
    res, baseline, trunk = pinned_contour(mask)
    return Exemplar(norm, trunk, res, simplified(res, size), baseline, name)


def normalize(rgba: np.ndarray, size: int = SIZE) -> np.ndarray:
    """``rgba`` cropped to its opaque box, padded square with :data:`MARGIN` and resized to
    ``(size, size, 4)`` uint8 (colour resized premultiplied)."""
    opaque = rgba[..., 3] >= ALPHA_T
    ys, xs = np.nonzero(opaque)
    crop = rgba[ys.min():ys.max() + 1, xs.min():xs.max() + 1].astype(np.float32)
    h, w = crop.shape[:2]
    side = int(np.ceil(max(h, w) / (1.0 - 2 * MARGIN)))
    sq = np.zeros((side, side, 4), np.float32)
    y0, x0 = (side - h) // 2, (side - w) // 2
    a = crop[..., 3:] / 255.0
    sq[y0:y0 + h, x0:x0 + w, :3] = crop[..., :3] * a          # premultiplied
    sq[y0:y0 + h, x0:x0 + w, 3] = crop[..., 3]
    interp = cv2.INTER_AREA if side > size else cv2.INTER_LINEAR
    out = cv2.resize(sq, (size, size), interpolation=interp)
    alpha = out[..., 3:] / 255.0
    rgb = np.where(alpha > 1e-3, out[..., :3] / np.maximum(alpha, 1e-3), 0.0)
    return np.clip(np.concatenate([rgb, out[..., 3:]], -1), 0, 255).round().astype(np.uint8)


def crown_baseline(mask: np.ndarray) -> tuple[int, np.ndarray]:
    """``(baseline row, trunk (H, W) bool)`` of a tree mask (module docstring, step 2)."""
    rows = np.nonzero(mask.any(1))[0]
    top, bottom = int(rows.min()), int(rows.max())
    height = bottom - top + 1
    cols = np.nonzero(mask.any(0))[0]
    width = int(cols.max() - cols.min() + 1)
    widths = mask.sum(1)
    foot = widths[max(bottom - max(int(BOTTOM * height), 1) + 1, top):bottom + 1]
    limit = min(TRUNK_WIDTH * float(np.median(foot)), TRUNK_SHARE * width)
    above = np.nonzero(widths[top:bottom + 1][::-1] > limit)[0]       # rows from the bottom up
    baseline = bottom - int(above[0]) if len(above) else top
    trunk = np.zeros_like(mask)
    if bottom - baseline >= MIN_TRUNK * height:
        trunk[baseline + 1:] = mask[baseline + 1:]
    else:
        baseline = bottom
    return baseline, trunk


def signed_area(poly: np.ndarray) -> float:
    """Shoelace area of ``poly (K, 2)`` in image coordinates (y down): negative when it runs bottom →
    right → top → left (counter-clockwise as seen)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def mirror_pinned(contour: np.ndarray) -> np.ndarray:
    """A pinned contour ``(N, 2)`` (x right) seen from behind: x negated about its point 0 (B) and
    the order reversed from B, so it again runs B → R → L (the old R is the new L)."""
    c = np.asarray(contour, np.float64).copy()
    c[:, 0] = 2.0 * c[0, 0] - c[:, 0]
    return np.concatenate([c[:1], c[1:][::-1]])


def oriented_contour(mask: np.ndarray) -> np.ndarray:
    """The longest external contour of ``mask`` ``(K, 2)`` float px, running up the right side from
    the bottom (negative :func:`signed_area`)."""
    cs, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(cs, key=len)[:, 0].astype(np.float64)
    return c[::-1].copy() if signed_area(c) > 0 else c


def pins(contour: np.ndarray, baseline: int | None) -> tuple[int, int, int]:
    """Indices ``(B, R, L)`` into ``contour`` (module docstring, step 4); without a ``baseline`` (no
    trunk) ``R = L = B``."""
    y = contour[:, 1]
    low = np.nonzero(y >= y.max() - 0.5)[0]
    b = int(low[len(low) // 2])
    if baseline is None:
        return b, b, b
    k = len(contour)
    order = (b + np.arange(k)) % k
    up = np.nonzero(contour[order, 1] <= baseline)[0]
    r = int(order[up[0]])
    back = (b - np.arange(k)) % k
    down = np.nonzero(contour[back, 1] <= baseline)[0]
    return b, r, int(back[down[0]])


def pinned_contour(mask: np.ndarray, counts: tuple[int, int, int] = (TRUNK_POINTS, CROWN_POINTS, TRUNK_POINTS)
                   ) -> tuple[np.ndarray, int, np.ndarray]:
    """``(contour (sum(counts), 2) px, baseline row, trunk (H, W) bool)`` of a tree mask: steps 2–5
    of the module docstring (crown and trunk, the oriented contour, its pins, resampled to ``counts``)."""
    baseline, trunk = crown_baseline(mask)
    contour = oriented_contour(mask)
    b, r, l_ = pins(contour, baseline if trunk.any() else None)
    return resample_pinned(contour, b, r, l_, counts), baseline, trunk


def resample_polyline(pts: np.ndarray, n: int) -> np.ndarray:
    """``n`` points at uniform arc length along ``pts (K, 2)`` from its first point, its last
    excluded (the next segment's first)."""
    if len(pts) < 2:
        return np.repeat(pts[:1], n, 0)
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return np.repeat(pts[:1], n, 0)
    t = np.arange(n) * (s[-1] / n)
    return np.stack([np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])], 1)


def resample_pinned(contour: np.ndarray, b: int, r: int, l_: int,
                    counts: tuple[int, int, int] = (TRUNK_POINTS, CROWN_POINTS, TRUNK_POINTS)) -> np.ndarray:
    """``(sum(counts), 2)``: B→R, R→L, L→B resampled to ``counts`` points (default
    :data:`TRUNK_POINTS`, :data:`CROWN_POINTS`, :data:`TRUNK_POINTS`; the contour runs B → R → L → B)."""
    k = len(contour)
    c = np.roll(contour, -b, axis=0)
    c = np.concatenate([c, c[:1]])                      # closed: index k is B again
    ri, li = (r - b) % k, (l_ - b) % k
    if ri == 0 and li == 0:                             # no trunk: the whole loop is crown
        ri, li = 0, k
    return np.concatenate([resample_polyline(c[:ri + 1], counts[0]),
                           resample_polyline(c[ri:li + 1], counts[1]),
                           resample_polyline(c[li:], counts[2])])


def simplified(contour: np.ndarray, size: int) -> np.ndarray:
    """The simplified contour of a resampled one (module docstring, step 6), ``(N_POINTS //
    SIMPLE_STEP, 2)`` px."""
    k = SIMPLE_STEP
    padded = np.concatenate([contour[-k:], contour, contour[:k]])
    kernel = np.ones(2 * k + 1) / (2 * k + 1)
    smooth = np.stack([np.convolve(padded[:, i], kernel, "valid") for i in range(2)], 1)[:len(contour)]
    pts = smooth[::k]
    tangent = np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0)
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], 1)              # outward for this orientation
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-9)
    return pts + normal * (DILATE * size)
