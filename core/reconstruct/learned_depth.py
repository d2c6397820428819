"""Learned depth (issue 35, seed 003 *single-image tree reconstruction*): what the product has in frame
1 — its edges, the tree's outline and the traced 2D skeleton — encoded as an image, and the depths a
single view cannot show predicted from it by a small U-Net trained on the project's synthetic trees
(``scripts/train_depth.py``) and run here through OpenCV's ``cv2.dnn`` (no PyTorch at run time).

Encoding (:func:`encode`, ``(IN_CHANNELS, SIZE, SIZE)`` float32 in [0, 1], the square crop
:func:`crop_box` around the outline): 0 the Canny edges of the grey frame, 1 the outline's mask,
2 the skeleton's segments (the seed's user strokes, drawn by the trace), 3 each segment's branching
order (the forks between it and the root, /4, at most 1: the seed's strokes coloured by branch),
4 its distance along the skeleton from the root over the longest such distance (branching order as
:func:`..topology.branching_level` counts it).

Prediction (:data:`OUT_CHANNELS` images, depths over ``H`` the tree's height in the image, in
[0, 1]): 0 the skeleton's distance from the plane through the trunk where the skeleton is drawn,
1 the crown's reach there (the largest distance from that plane of the leaves and branches the pixel
shows) and 2 their depth interval (front to back; the seed's *dual depth*). Distances, not signed
depths: one view cannot tell in front of the trunk's plane from behind it, and a network fitted to
signed depths sinks to the plane (measured: its crowns spanned ±0.05 H where the true ones spanned
±0.4 H); the lift chooses the side (:mod:`.lift`).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..topology import branching_level

#: where the lift takes the depth a single view cannot show: the outline's surface of revolution
#: (the paper's envelope) or this network (``--depth``)
DEPTH_SOURCES = ("envelope", "learned")
#: the network's input and output side, px
SIZE = 128
IN_CHANNELS = 5
OUT_CHANNELS = 3
#: the crop's margin around the outline's box, share of its longer side, each way
MARGIN = 0.06
#: Canny thresholds on the grey crop (after a 3×3 Gaussian), 8-bit levels
CANNY = (60, 150)
#: the forks that make branching order 1.0 in channel 3
ORDER_SCALE = 4.0
#: the shipped model (exported by scripts/train_depth.py)
MODEL_PATH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "models", "depth_unet.onnx")


@dataclass(frozen=True)
class CropBox:
    """A square of the frame: top-left ``(x0, y0)`` and ``side``, frame px; crop px = (frame px −
    corner) · SIZE / side."""

    x0: float
    y0: float
    side: float

    def to_crop(self, pts: np.ndarray, size: int = SIZE) -> np.ndarray:
        """``(..., 2)`` frame px → crop px."""
        return (np.asarray(pts, np.float64) - (self.x0, self.y0)) * (size / self.side)

    def affine(self, size: int = SIZE) -> np.ndarray:
        """The ``(2, 3)`` frame → crop matrix for ``cv2.warpAffine``."""
        s = size / self.side
        return np.array([[s, 0.0, -s * self.x0], [0.0, s, -s * self.y0]])


def crop_box(mask: np.ndarray, margin: float = MARGIN) -> CropBox:
    """The square around the ``(H, W)`` mask's box, ``margin`` of its longer side added each way."""
    ys, xs = np.nonzero(mask)
    if len(xs) == 0:
        raise ValueError("empty outline mask")
    x0, x1, y0, y1 = xs.min(), xs.max() + 1.0, ys.min(), ys.max() + 1.0
    side = max(x1 - x0, y1 - y0) * (1.0 + 2.0 * margin)
    return CropBox(0.5 * (x0 + x1) - 0.5 * side, 0.5 * (y0 + y1) - 0.5 * side, float(side))


def ancestor_sums(parents: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``(N,)`` Σ ``w`` over each node's proper ancestors (``parents[root] = −1``), by pointer
    jumping: ``acc[i]`` covers the path from ``i`` (excluded) to ``up[i]`` (included), and one jump
    ``acc[i] += acc[up[i]]``, ``up[i] = up[up[i]]`` doubles it (log₂ depth rounds, no per-node loop)."""
    parents = np.asarray(parents, np.int64)
    w = np.asarray(w, np.float64)
    up = parents.copy()
    acc = np.where(up >= 0, w[np.maximum(up, 0)], 0.0)
    while np.any(up >= 0):
        j = up >= 0
        s = np.maximum(up, 0)
        acc, up = np.where(j, acc + acc[s], acc), np.where(j, up[s], -1)
    return acc


def tree_height_px(mask: np.ndarray) -> float:
    """The tree's height in the image, px: the outline mask's rows from top to bottom (the scale of
    every predicted depth)."""
    rows = np.nonzero(np.any(mask, axis=1))[0]
    if len(rows) == 0:
        raise ValueError("empty outline mask")
    return float(rows[-1] - rows[0] + 1)


def path_length(nodes: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """``(N,)`` distance along the skeleton from the root to each node, in the units of ``nodes (N, 2)``."""
    parents = np.asarray(parents, np.int64)
    seg = np.where(parents >= 0, np.linalg.norm(nodes - nodes[np.maximum(parents, 0)], axis=1), 0.0)
    return seg + ancestor_sums(parents, seg)


def segment_samples(a: np.ndarray, b: np.ndarray, step: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points every ``step`` px along the segments ``a[k] → b[k]`` (``(S, 2)`` each): ``(P, 2)`` points,
    ``(P,)`` their segment, ``(P,)`` their fraction along it (0 at ``a``)."""
    ln = np.linalg.norm(b - a, axis=1)
    n = np.maximum(np.ceil(ln / step).astype(np.int64), 1) + 1
    seg = np.repeat(np.arange(len(a)), n)
    start = np.cumsum(n) - n
    t = (np.arange(len(seg)) - start[seg]) / np.maximum(n[seg] - 1, 1)
    return a[seg] + (b[seg] - a[seg]) * t[:, None], seg, t


def splat(pts: np.ndarray, values: np.ndarray, size: int, reduce: str = "max",
          fill: float = 0.0) -> np.ndarray:
    """``(size, size)`` image of ``values (P,)`` at the nearest pixels of ``pts (P, 2)`` (x, y),
    ``reduce`` "max" or "min" where several fall on one pixel, ``fill`` elsewhere."""
    ij = np.floor(pts).astype(np.int64)
    ok = (ij[:, 0] >= 0) & (ij[:, 0] < size) & (ij[:, 1] >= 0) & (ij[:, 1] < size)
    flat = ij[ok, 1] * size + ij[ok, 0]
    v = values[ok].astype(np.float64)
    if reduce == "max":
        img = np.full(size * size, -np.inf)
        np.maximum.at(img, flat, v)
    else:
        img = np.full(size * size, np.inf)
        np.minimum.at(img, flat, v)
    img[~np.isfinite(img)] = fill
    return img.reshape(size, size)


def draw_skeleton(nodes_crop: np.ndarray, parents: np.ndarray, size: int = SIZE) -> np.ndarray:
    """Channels 2–4 of :func:`encode` ``(3, size, size)``: the segments of the skeleton ``nodes_crop
    (N, 2)`` crop px, their branching order / ORDER_SCALE and their path length / the longest."""
    parents = np.asarray(parents, np.int64)
    child = np.nonzero(parents >= 0)[0]
    out = np.zeros((3, size, size), np.float32)
    if len(child) == 0:
        return out
    order = np.minimum(branching_level(parents) / ORDER_SCALE, 1.0)
    plen = path_length(nodes_crop, parents)
    plen = plen / max(float(plen.max()), 1e-9)
    pts, seg, t = segment_samples(nodes_crop[parents[child]], nodes_crop[child])
    c = child[seg]
    out[0] = splat(pts, np.ones(len(pts)), size)
    out[1] = splat(pts, order[c], size)
    out[2] = splat(pts, plen[parents[c]] + (plen[c] - plen[parents[c]]) * t, size)
    return out


def encode(gray: np.ndarray, mask: np.ndarray, nodes2d: np.ndarray, parents: np.ndarray,
           box: CropBox | None = None, size: int = SIZE) -> tuple[np.ndarray, CropBox]:
    """The network's input ``(IN_CHANNELS, size, size)`` float32 from frame 1's grey image ``(H, W)``
    uint8, the outline's mask ``(H, W)`` bool and the traced skeleton ``nodes2d (N, 2)`` frame px
    with its ``parents (N,)``; and the crop (``box``: by default :func:`crop_box` of the mask)."""
    import cv2
    box = box or crop_box(mask)
    M = box.affine(size)
    g = cv2.warpAffine(gray, M, (size, size), flags=cv2.INTER_AREA, borderMode=cv2.BORDER_REPLICATE)
    edges = cv2.Canny(cv2.GaussianBlur(g, (3, 3), 0), *CANNY)
    m = cv2.warpAffine(mask.astype(np.uint8) * 255, M, (size, size), flags=cv2.INTER_LINEAR) >= 128
    x = np.zeros((IN_CHANNELS, size, size), np.float32)
    x[0] = edges > 0
    x[1] = m
    x[2:] = draw_skeleton(box.to_crop(nodes2d, size), parents, size)
    return x, box


def to_unit(d_over_h: np.ndarray) -> np.ndarray:
    """Depth / height → the network's unit depth ``½ + ½·clip(d / H, −1, 1)``."""
    return 0.5 + 0.5 * np.clip(d_over_h, -1.0, 1.0)


def from_unit(u: np.ndarray) -> np.ndarray:
    """Unit depth → depth / height (the inverse of :func:`to_unit` inside ±1)."""
    return 2.0 * np.asarray(u, np.float64) - 1.0


@dataclass
class DepthImages:
    """A prediction over the frame's square ``box``, each ``(SIZE, SIZE)`` depth / the tree's image
    height: ``distance`` the skeleton's from the trunk's plane, ``reach`` the crown's, ``interval``
    the crown's front to back."""

    distance: np.ndarray
    reach: np.ndarray
    interval: np.ndarray
    box: CropBox

    def sample(self, image: np.ndarray, pts: np.ndarray) -> np.ndarray:
        """``image`` (one of the three) at frame px ``pts (P, 2)``, bilinear; edge values outside."""
        c = np.clip(self.box.to_crop(pts, image.shape[0]) - 0.5, 0.0, image.shape[0] - 1.0)
        i0 = np.minimum(np.floor(c).astype(np.int64), image.shape[0] - 2)
        f = c - i0
        a = image[i0[:, 1], i0[:, 0]] * (1 - f[:, 0]) + image[i0[:, 1], i0[:, 0] + 1] * f[:, 0]
        b = image[i0[:, 1] + 1, i0[:, 0]] * (1 - f[:, 0]) + image[i0[:, 1] + 1, i0[:, 0] + 1] * f[:, 0]
        return a * (1 - f[:, 1]) + b * f[:, 1]


def decode(out: np.ndarray, box: CropBox) -> DepthImages:
    """The network's ``(OUT_CHANNELS, S, S)`` output in [0, 1] → :class:`DepthImages`."""
    out = np.clip(np.asarray(out, np.float64), 0.0, 1.0)
    return DepthImages(distance=out[0], reach=out[1], interval=out[2], box=box)


_NETS: dict = {}


def shared_net(path: str = MODEL_PATH) -> "DepthNet":
    """The model at ``path``, read once per process."""
    if path not in _NETS:
        _NETS[path] = DepthNet(path)
    return _NETS[path]


class DepthNet:
    """The ONNX U-Net through ``cv2.dnn`` (``path``: :data:`MODEL_PATH`) and its measured fit
    (``fit``, :func:`measured_fit` of the JSON beside it); :meth:`run` maps an encoded input
    ``(IN_CHANNELS, S, S)`` to the unit output ``(OUT_CHANNELS, S, S)``."""

    def __init__(self, path: str = MODEL_PATH):
        import cv2
        if not os.path.isfile(path):
            raise FileNotFoundError(f"no depth model at {path}; run scripts/train_depth.py")
        self.net = cv2.dnn.readNetFromONNX(path)
        self.path = path
        self.fit = measured_fit(os.path.splitext(path)[0] + ".json")    # (3,) its held-out errors

    def run(self, x: np.ndarray) -> np.ndarray:
        """``(OUT_CHANNELS, S, S)`` in [0, 1] (the network's tanh mapped)."""
        self.net.setInput(np.ascontiguousarray(x[None], np.float32))
        y = np.asarray(self.net.forward())[0]
        return (y + 1.0) * 0.5

    def predict(self, gray: np.ndarray, mask: np.ndarray, nodes2d: np.ndarray, parents: np.ndarray) -> DepthImages:
        x, box = encode(gray, mask, nodes2d, parents)
        return decode(self.run(x), box)


#: the shipped model's measured errors (depth / height, mean absolute over the held-out trees' pixels
#: per output), written by scripts/train_depth.py beside the model
FIT_PATH = os.path.splitext(MODEL_PATH)[0] + ".json"


def measured_fit(path: str = FIT_PATH) -> np.ndarray:
    """``(3,)`` the model's held-out errors as depth / height (the skeleton's distance, the crown's
    reach, its interval): how far to trust a prediction (the lift's prior width)."""
    import json
    with open(path, encoding="utf-8") as fh:
        doc = json.load(fh)
    return np.asarray(doc["test_mae_over_height"], np.float64)


def crown_depth_scale(depth: DepthImages, env, mask: np.ndarray, limits: tuple[float, float] = (0.1, 2.0)) -> float:
    """How deep the crown is against the outline turned about its axis (``env``, whose depth is its
    width): the predicted crown's reach (its 95th percentile over the outline's pixels, px) over
    ``env``'s largest radius, within ``limits`` — the depth scale of an elliptic Ω."""
    ys, xs = np.nonzero(mask)
    r = float(env.radius.max()) if len(env.radius) else 0.0
    if len(xs) == 0 or r <= 0:
        return 1.0
    step = max(1, len(xs) // 4000)
    xy = np.stack([xs[::step], ys[::step]], 1).astype(np.float64)
    reach = float(np.percentile(depth.sample(depth.reach, xy), 95)) * tree_height_px(mask)
    return float(np.clip(reach / r, *limits))
