"""Stage 2 — the user's outline of the tree in frame 1, as a polygon and a mask.

Accepted inputs: a JSON file holding a list of ``[x, y]`` pixel vertices (or an object with a
``"polygon"`` key holding that list), or a mask image (any non-zero pixel is inside).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import cv2
import numpy as np

from .errors import InputError
from .fileio import read_json

MIN_AREA_PX = 64.0  # smaller outlines cannot hold a tree's worth of corners


@dataclass
class Outline:
    """``polygon (M, 2)`` float32 pixels (x right, y down); ``mask (H, W)`` bool, True inside."""

    polygon: np.ndarray
    mask: np.ndarray

    @property
    def bbox(self) -> tuple[int, int, int, int]:
        """``(x0, y0, x1, y1)`` pixel bounds of the mask (inclusive-exclusive)."""
        ys, xs = np.nonzero(self.mask)
        return int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1


def polygon_to_mask(polygon: np.ndarray, width: int, height: int) -> np.ndarray:
    """Fill ``polygon (M, 2)`` pixels into a ``(height, width)`` bool mask."""
    mask = np.zeros((height, width), np.uint8)
    cv2.fillPoly(mask, [np.round(polygon).astype(np.int32).reshape(-1, 1, 2)], 1)
    return mask.astype(bool)


#: a mask component is a tree of its own when it is at least this share of the largest one's area
#: (smaller ones are specks of the paint: with one tree they stay in its mask, as they always did)
TREE_COMPONENT_SHARE = 0.1


def _is_polygon_list(data) -> bool:
    """Whether JSON ``data`` is a list of polygons (``[[[x, y], ...], ...]``) rather than one."""
    return (isinstance(data, list) and len(data) > 0 and all(isinstance(p, list) for p in data)
            and all(len(p) > 0 and isinstance(p[0], list) for p in data))


def _read_polygons(path: str) -> list[np.ndarray]:
    """The polygons of an outline .json: one (``[[x, y], ...]``, ``{"polygon": ...}``) or several
    (``[[[x, y], ...], ...]``, ``{"polygons": [...]}``)."""
    data = read_json(path, f"outline '{path}'", "give a JSON list of [x, y] pixel points or a mask PNG")
    if isinstance(data, dict) and "polygons" in data:
        data = data["polygons"]
    if _is_polygon_list(data):
        return [_as_polygon(p, f"{path}, polygon {k + 1}") for k, p in enumerate(data)]
    return [_read_polygon(path, data)]


def _as_polygon(data, path: str) -> np.ndarray:
    try:
        poly = np.asarray(data, dtype=np.float64)
    except (TypeError, ValueError):
        poly = np.zeros((0,))
    if poly.ndim != 2 or poly.shape[1] != 2 or not np.all(np.isfinite(poly)):
        raise InputError(f"outline '{path}' does not hold a list of [x, y] points; "
                         "write it as [[x1, y1], [x2, y2], ...] in pixels of frame 1")
    return poly


def _read_polygon(path: str, data=None) -> np.ndarray:
    if data is None:
        data = read_json(path, f"outline '{path}'", "give a JSON list of [x, y] pixel points or a mask PNG")
    if isinstance(data, dict):
        data = data.get("polygon", data.get("points"))
    return _as_polygon(data, path)


def _mask_to_polygon(mask: np.ndarray) -> np.ndarray:
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return np.zeros((0, 2))
    return max(contours, key=cv2.contourArea).reshape(-1, 2).astype(np.float64)


def polygon_outline(polygon, width: int, height: int, name: str = "outline") -> Outline:
    """An :class:`Outline` from a polygon ``(M, 2)`` in pixels of the (scaled) frame, validated
    like a file (at least 3 points, not degenerate, inside the frame)."""
    poly = np.asarray(polygon, dtype=np.float64).reshape(-1, 2) if len(polygon) else np.zeros((0, 2))
    if len(poly) < 3 or not np.all(np.isfinite(poly)):
        raise InputError(f"{name} has {len(poly)} usable point(s); draw at least 3 around the tree")
    poly_area = abs(float(cv2.contourArea(poly.astype(np.float32))))
    if poly_area < MIN_AREA_PX:
        raise InputError(f"{name} is degenerate (area {poly_area:.0f} px²); draw a polygon around the whole tree")
    mask = polygon_to_mask(poly, width, height)
    area = float(mask.sum())
    if area == 0:
        raise InputError(f"{name} lies outside the {width}x{height} frame; "
                         "give coordinates in pixels of the video's first frame")
    if area < 0.5 * poly_area:
        raise InputError(f"{name} lies mostly outside the {width}x{height} frame "
                         f"({100 * area / poly_area:.0f}% inside); use pixels of the first frame")
    return Outline(poly.astype(np.float32), mask)


def load_outline(path: str | os.PathLike, width: int, height: int, scale: float = 1.0) -> Outline:
    """Read a polygon JSON or mask image for a ``width`` x ``height`` frame (after ``scale``).

    Polygon coordinates are in pixels of the original video and are multiplied by ``scale``; a
    mask image of another size is resized to the frame. Raises :class:`InputError` when the outline
    is missing, empty, degenerate (fewer than 3 points or under 64 px²) or outside the frame.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"outline '{path}' does not exist; give a polygon .json or a mask .png")
    if path.lower().endswith(".json"):
        return polygon_outline(_read_polygon(path) * scale, width, height, f"outline '{path}'")
    img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise InputError(f"outline '{path}' is neither JSON nor a readable image; "
                         "give a polygon .json or a black/white mask .png")
    if img.shape != (height, width):
        img = cv2.resize(img, (width, height), interpolation=cv2.INTER_NEAREST)
    mask = img > 0
    if not mask.any():
        raise InputError(f"outline mask '{path}' is empty (all black); paint the tree white")
    if mask.sum() < MIN_AREA_PX:
        raise InputError(f"outline mask '{path}' is degenerate (area {int(mask.sum())} px²); "
                         "paint the whole tree white")
    return Outline(_mask_to_polygon(mask).astype(np.float32), mask)


def load_outlines(path: str | os.PathLike, width: int, height: int, scale: float = 1.0) -> list[Outline]:
    """The trees outlined in one file, for a ``width`` x ``height`` frame (after ``scale``): each
    polygon of a .json holding several (``[[[x, y], ...], ...]`` or ``{"polygons": [...]}``), each
    component of a mask image at least :data:`TREE_COMPONENT_SHARE` of the largest one's area, or
    the one outline :func:`load_outline` reads. Raises :class:`InputError` as it does, naming the
    polygon."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"outline '{path}' does not exist; give a polygon .json or a mask .png")
    if path.lower().endswith(".json"):
        polys = _read_polygons(path)
        if len(polys) == 1:
            return [load_outline(path, width, height, scale)]
        return [polygon_outline(p * scale, width, height, f"outline '{path}', polygon {k + 1}")
                for k, p in enumerate(polys)]
    one = load_outline(path, width, height, scale)
    parts = separate_regions(one.mask, TREE_COMPONENT_SHARE, MIN_AREA_PX)
    if len(parts) <= 1:
        return [one]
    return [Outline(_mask_to_polygon(m).astype(np.float32), m) for m in parts]


def largest_component(mask: np.ndarray) -> np.ndarray:
    """``mask (H, W)`` bool with only its largest 8-connected part (unchanged when it has one or
    none: test ``.any()`` for an empty one)."""
    n, lab, stats, _ = cv2.connectedComponentsWithStats(np.asarray(mask, np.uint8), connectivity=8)
    if n <= 2:
        return np.asarray(mask, bool)
    return lab == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))


def separate_regions(mask: np.ndarray, share: float, min_area: float = 0.0) -> list[np.ndarray]:
    """The 8-connected regions of ``mask (H, W)`` bool at least ``share`` of the largest one's area
    (and ``min_area`` px), each a bool mask, left to right: one tree each (a painted mask's
    parts, the automatic outline's swaying regions)."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats(np.asarray(mask, np.uint8), connectivity=8)
    if n < 2:
        return []
    area = stats[1:, cv2.CC_STAT_AREA]
    big = np.flatnonzero(area >= max(share * area.max(), min_area)) + 1
    big = big[np.argsort(stats[big, cv2.CC_STAT_LEFT], kind="stable")]
    return [labels == k for k in big]
