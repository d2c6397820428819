"""Envelopes Ω' for generated trees (paper §5.3, Fig. 11 "tree topiary").

Every envelope is a :class:`ShapeEnvelope`: the lift's surface of revolution
(:class:`~..envelope.Envelope`: per height a centre and a radius, metres) plus the exact 2D outline
``polygon (M, 2)`` in (x, z) metres that the 2D growth fills. Trunk base at the origin, z up, the
lowest point of the shape at z = 0.

Sources: built-in topiary shapes (:func:`topiary`: triangle, circle, pentagon, heart — a crown on a
short stem so the trunk has somewhere to stand), a closed curve (:func:`envelope_from_polygon`,
e.g. points sampled from a Blender curve), an image silhouette (:func:`envelope_from_image`), or
a reconstructed tree's envelope (``envelope.envelope_from_meta``; its 2D region is
``|x − centre(z)| ≤ radius(z)``).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import cv2
import numpy as np

from ..envelope import Envelope, envelope_from_outline
from ..errors import InputError
from ..meta import EnvelopeMeta
from ..outline import Outline, largest_component

SHAPES = ("triangle", "circle", "pentagon", "heart")
RASTER_ROWS = 400            # rows of the raster a shape is turned into (cell = height / 400)


@dataclass
class ShapeEnvelope(Envelope):
    """An :class:`Envelope` (metres) that also keeps the exact 2D outline: ``polygon (M, 2)``
    (x, z) metres, counter-clockwise or not, not closed (last ≠ first); ``name``; ``offset (2,)``
    metres that were subtracted from the input coordinates to put the base at the origin."""

    polygon: np.ndarray | None = None
    name: str = "outline"
    offset: np.ndarray | None = None


def envelope_polygon(env: Envelope) -> np.ndarray:
    """``(M, 2)`` (x, z) metres outline of any envelope: its polygon, or for a plain surface of
    revolution the left edge upward then the right edge downward."""
    poly = getattr(env, "polygon", None)
    if poly is not None and len(poly) >= 3:
        return np.asarray(poly, np.float64)
    left = np.stack([env.centre - env.radius, env.z], 1)
    right = np.stack([env.centre + env.radius, env.z], 1)[::-1]
    return np.concatenate([left, right])


class Region2D:
    """Ω' as a raster for fast point tests: ``mask (H, W)`` bool, row 0 at the top
    (z = ``z_top``), cell size ``cell`` metres, column 0 at x = ``x0``. The mask is eroded by one
    cell, so a point the raster calls inside is inside the true outline."""

    def __init__(self, polygon: np.ndarray, rows: int = RASTER_ROWS):
        poly = np.asarray(polygon, np.float64)
        lo, hi = poly.min(0), poly.max(0)
        self.cell = float(max(hi[1] - lo[1], hi[0] - lo[0], 1e-6)) / rows
        self.x0 = float(lo[0]) - 2 * self.cell
        self.z_top = float(hi[1]) + 2 * self.cell
        W = int(np.ceil((hi[0] - lo[0]) / self.cell)) + 5
        H = int(np.ceil((hi[1] - lo[1]) / self.cell)) + 5
        px = self.to_px(poly)
        m = np.zeros((H, W), np.uint8)
        cv2.fillPoly(m, [np.round(px * 16).astype(np.int32).reshape(-1, 1, 2)], 1, lineType=cv2.LINE_8, shift=4)
        self.full = m.astype(bool)
        self.mask = cv2.erode(m, np.ones((3, 3), np.uint8)).astype(bool)
        self.polygon = poly

    def to_px(self, p: np.ndarray) -> np.ndarray:
        """(x, z) metres ``(..., 2)`` → (column, row) float pixel coordinates."""
        p = np.asarray(p, np.float64)
        return np.stack([(p[..., 0] - self.x0) / self.cell, (self.z_top - p[..., 1]) / self.cell], -1)

    def contains(self, p: np.ndarray) -> np.ndarray:
        """``(...)`` bool for (x, z) metres ``p (..., 2)``."""
        return self.sample(self.mask, p)

    def sample(self, grid: np.ndarray, p: np.ndarray) -> np.ndarray:
        """``(...)`` bool: ``grid`` (a mask on this region's raster, e.g. :attr:`mask` or a dilated
        :attr:`full`) at the nearest pixel of (x, z) metres ``p (..., 2)``; False off the raster."""
        q = np.round(self.to_px(p)).astype(np.int64)
        H, W = grid.shape
        ok = (q[..., 0] >= 0) & (q[..., 0] < W) & (q[..., 1] >= 0) & (q[..., 1] < H)
        out = np.zeros(q.shape[:-1], bool)
        out[ok] = grid[q[..., 1][ok], q[..., 0][ok]]
        return out

    @property
    def area(self) -> float:
        """m² of the (eroded) region."""
        return float(self.mask.sum()) * self.cell ** 2

    def attractors(self, n: int) -> np.ndarray:
        """About ``n`` points ``(K, 2)`` (x, z) metres spread evenly over the region's area (a
        square grid of spacing ``sqrt(area / n)``, centred in its cells)."""
        rows, cols = np.nonzero(self.mask)
        if len(rows) == 0:
            return np.zeros((0, 2))
        step = max(1, int(round(np.sqrt(len(rows) / max(n, 1)))))
        keep = (rows % step == step // 2) & (cols % step == step // 2)
        if keep.sum() < 3:
            keep = np.ones(len(rows), bool)
        return np.stack([self.x0 + cols[keep] * self.cell, self.z_top - rows[keep] * self.cell], 1)

    def width_at(self, z: np.ndarray) -> np.ndarray:
        """Width (metres) of the region's row at heights ``z``."""
        r = np.clip(np.round((self.z_top - np.asarray(z, float)) / self.cell).astype(int), 0, self.mask.shape[0] - 1)
        return self.mask[r].sum(1) * self.cell

    def height(self) -> float:
        rows = np.flatnonzero(self.mask.any(1))
        return float((rows.max() - rows.min()) * self.cell) if len(rows) else 0.0


def region_of(env: Envelope, rows: int = RASTER_ROWS) -> Region2D:
    """The 2D region Ω' of ``env`` (its polygon, or ``|x − c(z)| ≤ r(z)``)."""
    return Region2D(envelope_polygon(env), rows)


def envelope_from_mask(mask: np.ndarray, metres_per_px: float, base_px: np.ndarray | None = None,
                       name: str = "outline") -> ShapeEnvelope:
    """A :class:`ShapeEnvelope` from an image-like ``mask (H, W)`` bool (row 0 at the top), scaled
    by ``metres_per_px``. ``base_px (2,)`` (x, y) is the trunk base; by default the middle of the
    mask's lowest row. Only the largest connected part is kept."""
    mask = largest_component(np.asarray(mask, bool))
    rows = np.flatnonzero(mask.any(1))
    if base_px is None:
        bottom = rows.max()
        cols = np.flatnonzero(mask[bottom])
        base_px = np.array([0.5 * (cols.min() + cols.max()), float(bottom)])
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    c = max(contours, key=cv2.contourArea).reshape(-1, 2).astype(np.float64)
    env = envelope_from_outline(Outline(c.astype(np.float32), mask), np.asarray(base_px, float))
    s = float(metres_per_px)
    poly = np.stack([(c[:, 0] - base_px[0]) * s, (base_px[1] - c[:, 1]) * s], 1)
    return ShapeEnvelope(env.z * s, env.centre * s, env.radius * s, polygon=poly, name=name, offset=np.zeros(2))


def rasterize(polys: list[np.ndarray], rows: int) -> tuple[np.ndarray, float, np.ndarray]:
    """Union of (x, z) metre polygons as a mask with ``rows`` rows over their height; returns
    (mask, metres per px, base_px = where (0, 0) lands)."""
    allp = np.concatenate(polys)
    lo, hi = allp.min(0), allp.max(0)
    s = float(max(hi[1] - lo[1], 1e-9)) / rows
    W = int(np.ceil((hi[0] - lo[0]) / s)) + 8
    H = rows + 8
    base = np.array([(0.0 - lo[0]) / s + 4, (hi[1] - 0.0) / s + 4])
    m = np.zeros((H, W), np.uint8)
    for p in polys:
        px = np.stack([(p[:, 0] - lo[0]) / s + 4, (hi[1] - p[:, 1]) / s + 4], 1)
        cv2.fillPoly(m, [np.round(px * 16).astype(np.int32).reshape(-1, 1, 2)], 1, lineType=cv2.LINE_8, shift=4)
    return m.astype(bool), s, base


def crown_polygon(shape: str, width: float, height: float, n: int = 96) -> np.ndarray:
    """``(M, 2)`` outline of a topiary crown ``width`` × ``height`` metres, bottom at z = 0,
    centred on x = 0. Heart: ``x = 16 sin³t``, ``y = 13 cos t − 5 cos 2t − 2 cos 3t − cos 4t``."""
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    if shape == "triangle":
        p = np.array([[-0.5, 0.0], [0.5, 0.0], [0.0, 1.0]])
    elif shape == "circle":
        p = np.stack([0.5 * np.cos(t), 0.5 + 0.5 * np.sin(t)], 1)
    elif shape == "pentagon":
        a = np.pi / 2 + np.arange(5) * 2 * np.pi / 5          # one corner up, flat bottom
        p = np.stack([np.cos(a), np.sin(a)], 1)
    elif shape == "heart":
        p = np.stack([16 * np.sin(t) ** 3, 13 * np.cos(t) - 5 * np.cos(2 * t) - 2 * np.cos(3 * t) - np.cos(4 * t)], 1)
    else:
        raise InputError(f"unknown topiary shape '{shape}'; choose one of {', '.join(SHAPES)}")
    lo, hi = p.min(0), p.max(0)
    p = (p - [0.5 * (lo[0] + hi[0]), lo[1]]) / (hi - lo)        # unit box, bottom-centre at origin
    return p * [width, height]


def topiary(shape: str, height_m: float, width_m: float | None = None, stem_frac: float = 0.15) -> ShapeEnvelope:
    """A built-in envelope: crown ``shape`` ("triangle", "circle", "pentagon", "heart") on a stem
    (``stem_frac`` of the height, 8 % of the width wide, overlapping the crown so they join),
    ``height_m`` tall in total and ``width_m`` wide (default 0.8 × height)."""
    shape = str(shape).lower()
    if shape not in SHAPES:
        raise InputError(f"unknown topiary shape '{shape}'; choose one of {', '.join(SHAPES)}")
    if not (np.isfinite(height_m) and height_m > 0):
        raise InputError(f"envelope height {height_m} m is not positive; give e.g. 6")
    width = float(width_m) if width_m is not None else 0.8 * float(height_m)
    if not (np.isfinite(width) and width > 0):
        raise InputError(f"envelope width {width_m} m is not positive; give e.g. 5 or leave it empty")
    stem_h = float(np.clip(stem_frac, 0.0, 0.6)) * height_m
    crown = crown_polygon(shape, width, height_m - stem_h) + [0.0, stem_h]
    sw = 0.08 * width
    overlap = 0.12 * (height_m - stem_h)
    stem = np.array([[-sw / 2, 0.0], [sw / 2, 0.0], [sw / 2, stem_h + overlap], [-sw / 2, stem_h + overlap]])
    mask, s, base = rasterize([crown, stem] if stem_h > 0 else [crown], RASTER_ROWS)
    env = envelope_from_mask(mask, s, base, shape)
    return env


def envelope_from_polygon(poly: np.ndarray, name: str = "curve") -> ShapeEnvelope:
    """Ω' from a closed curve's points ``poly (M, 2)`` (x, z) metres (e.g. sampled from a Blender
    curve object seen from the front). The shape is moved so its lowest point is at z = 0 and the
    middle of its lowest part at x = 0 (``offset`` is what was subtracted)."""
    p = np.asarray(poly, np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3 or not np.all(np.isfinite(p)):
        raise InputError(f"the envelope curve has {len(p) if p.ndim else 0} usable point(s); "
                         "draw a closed curve with at least 3 points (front view, x and z)")
    area = 0.5 * abs(float(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1))))
    size = float(np.ptp(p[:, 1]))
    if size <= 0 or area < 1e-4 * max(size, np.ptp(p[:, 0])) ** 2:
        raise InputError("the envelope curve encloses no area (flat or a line); draw a closed outline "
                         "in the front (x-z) view")
    mask, s, _ = rasterize([p], RASTER_ROWS)
    env = envelope_from_mask(mask, s, None, name)
    # where the raster's base (bottom middle) lies in the curve's coordinates
    lo = p.min(0)
    rows = np.flatnonzero(mask.any(1))
    cols = np.flatnonzero(mask[rows.max()])
    base_x = lo[0] + (0.5 * (cols.min() + cols.max()) - 4) * s
    env.offset = np.array([base_x, lo[1]])
    return env


def envelope_from_image(path: str | os.PathLike, height_m: float) -> ShapeEnvelope:
    """Ω' from an image silhouette (paper Fig. 11, the vase): the non-transparent pixels of an
    image with an alpha channel, else the dark pixels (Otsu threshold; if the border is dark —
    a white shape on black — the bright ones). The largest connected part is kept and scaled to
    ``height_m`` metres; the base is the middle of its lowest row. :class:`InputError` for a
    missing, unreadable or empty image."""
    path = os.fspath(path)
    if not (np.isfinite(height_m) and height_m > 0):
        raise InputError(f"envelope height {height_m} m is not positive; give e.g. 6")
    if not os.path.isfile(path):
        raise InputError(f"envelope image '{path}' does not exist; give a PNG/JPEG silhouette")
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None or img.size == 0:
        raise InputError(f"envelope image '{path}' is not a readable image; give a PNG/JPEG silhouette")
    if img.dtype != np.uint8:
        img = cv2.convertScaleAbs(img, alpha=255.0 / max(float(img.max()), 1.0))
    scale = 800.0 / max(img.shape[:2])
    if scale < 1.0:
        img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    if img.ndim == 3 and img.shape[2] == 4 and img[..., 3].min() < 250:
        sil = img[..., 3] > 127
    else:
        gray = img if img.ndim == 2 else cv2.cvtColor(img[..., :3], cv2.COLOR_BGR2GRAY)
        if int(gray.max()) - int(gray.min()) < 8:
            raise InputError(f"envelope image '{path}' is blank (one flat colour); give a dark silhouette "
                             "on a light background or a PNG with transparency")
        thr, _ = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        sil = gray <= thr
        border = np.concatenate([sil[0], sil[-1], sil[:, 0], sil[:, -1]])
        if border.mean() > 0.5:
            sil = ~sil
    if sil.sum() < 64:
        raise InputError(f"envelope image '{path}' has no silhouette (under 64 pixels); give a dark shape "
                         "on a light background or a PNG with transparency")
    sil = largest_component(sil)
    rows = np.flatnonzero(sil.any(1))
    env = envelope_from_mask(sil, float(height_m) / max(rows.max() - rows.min() + 1, 1), None,
                             os.path.splitext(os.path.basename(path))[0])
    return env


def envelope_meta(env: Envelope) -> EnvelopeMeta:
    """JSON-able ``{"z", "centre", "radius"}`` metres (as ``envelope.envelope_to_meta``) plus the
    2D ``polygon`` and ``name`` when known."""
    from ..envelope import envelope_to_meta
    out = envelope_to_meta(env, 1.0)
    poly = getattr(env, "polygon", None)
    if poly is not None:
        out["polygon"] = np.asarray(poly, float).round(5).tolist()
        out["name"] = getattr(env, "name", "outline")
    return out


def envelope_doc(env: Envelope) -> dict:
    """``env`` as JSON-able full-precision lists (``z``, ``centre``, ``radius``, ``depth_scale``; a
    :class:`ShapeEnvelope`'s ``polygon``, ``name``, ``offset``): :func:`envelope_from_doc` gives it
    back exactly (what a generated tree keeps to be grown again)."""
    doc: dict = {k: np.asarray(getattr(env, k), np.float64).tolist() for k in ("z", "centre", "radius")}
    doc["depth_scale"] = float(env.depth_scale)
    if isinstance(env, ShapeEnvelope):
        doc.update(polygon=None if env.polygon is None else np.asarray(env.polygon, np.float64).tolist(),
                   name=env.name, offset=None if env.offset is None else np.asarray(env.offset, np.float64).tolist())
    return doc


def envelope_from_doc(doc: dict) -> Envelope:
    """The envelope :func:`envelope_doc` wrote."""
    arrays = {k: np.asarray(doc[k], np.float64) for k in ("z", "centre", "radius")}
    if "polygon" not in doc:
        return Envelope(**arrays, depth_scale=float(doc.get("depth_scale", 1.0)))
    return ShapeEnvelope(**arrays, depth_scale=float(doc.get("depth_scale", 1.0)),
                         polygon=None if doc["polygon"] is None else np.asarray(doc["polygon"], np.float64),
                         name=str(doc.get("name", "outline")),
                         offset=None if doc.get("offset") is None else np.asarray(doc["offset"], np.float64))


def envelope_from_any(spec, height_m: float, width_m: float | None = None) -> ShapeEnvelope | Envelope:
    """An envelope from a user-facing spec: a topiary name, an image path, an ``(M, 2)`` polygon
    or an :class:`Envelope` (returned as is)."""
    if isinstance(spec, Envelope):
        return spec
    if isinstance(spec, str) and spec.lower() in SHAPES:
        return topiary(spec, height_m, width_m)
    if isinstance(spec, (str, os.PathLike)):
        return envelope_from_image(spec, height_m)
    return envelope_from_polygon(np.asarray(spec, float))
