"""New tree images from RGBA exemplars (issue 36 part 2; seed 000 §5): a new contour as a convex
combination of the exemplars' contours, filled with their colour and alpha through mean value
coordinates.

1. **Contour synthesis** (§5.1): ``u' = Σ_j w_j u_j`` with ``w_j ≥ 0``, ``Σ w_j = 1`` (no negative
   weight: it would reflect a contour), over the pinned contours of :mod:`.exemplars` (index k is
   the same place on every tree). The weights of ``n`` variations are spread over the simplex:
   :data:`CANDIDATES` × n flat Dirichlet draws, none above :data:`MAX_WEIGHT` (a variation is not
   one exemplar again), chosen greedily farthest apart (the first farthest from the exemplars'
   mean). One exemplar is given its mirror image as the second.
2. **Colour transfer** (§5.2): each target pixel's mean value coordinates over the target's
   simplified contour ``C_s' = Σ w_j C_s,j``, applied to exemplar j's ``C_s,j``, give the pixel of
   exemplar j it shows (:mod:`.mvc`); sampled bilinearly, premultiplied. Alpha ``a' = max_j a_j``
   over the exemplars with weight > 0; colour a convex combination of theirs with random weights,
   among those with alpha > 0 (the seed's rule). Nothing outside the new contour dilated by the
   simplified contour's offset is kept. The exemplars' trunks are carried the same way
   (``trunk``), so a variation knows its trunk.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ..params import param
from ..progress import ProgressFn, report
from .exemplars import ALPHA_T, CROWN_POINTS, DILATE, TRUNK_POINTS, Exemplar
from .mvc import warp_map

#: weight candidates drawn per variation before the farthest are kept
CANDIDATES = 64
#: no exemplar weighs more than this in a variation of two or more
MAX_WEIGHT = 0.85


@dataclass
class VariationParams:
    """``count`` new trees from the exemplars, each ``size`` px square, drawn with ``seed``."""

    count: int = param(4, 1, 1000, what="--variations")
    size: int = param(512, 64, 4096, what="the variations' size", unit="px")
    seed: int = 0


@dataclass
class Variation:
    """One new tree: ``rgba (S, S, 4)`` uint8 straight alpha, ``trunk (S, S)`` bool its trunk's pixels,
    ``contour (N_POINTS, 2)`` px, ``weights (J,)`` the exemplars' in the contour, ``colour (J,)`` in
    the colour (0 for an exemplar not used)."""

    rgba: np.ndarray
    trunk: np.ndarray
    contour: np.ndarray
    weights: np.ndarray
    colour: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def aspect(self) -> float:
        """Width over height of the opaque pixels' box."""
        return box_aspect(self.rgba[..., 3] >= ALPHA_T)


def box_aspect(mask: np.ndarray) -> float:
    """Width / height of ``mask``'s box (0 when empty)."""
    ys, xs = np.nonzero(mask)
    if len(ys) == 0:
        return 0.0
    return float(xs.max() - xs.min() + 1) / float(ys.max() - ys.min() + 1)


def spread_weights(n_exemplars: int, count: int, rng: np.random.Generator) -> np.ndarray:
    """``(count, n_exemplars)`` convex weights spread over the simplex (module docstring, step 1)."""
    if n_exemplars == 1:
        return np.ones((count, 1))
    draws = rng.dirichlet(np.ones(n_exemplars), size=CANDIDATES * count)
    ok = draws.max(1) <= MAX_WEIGHT
    cand = draws[ok] if ok.any() else draws
    chosen = [int(np.argmax(np.linalg.norm(cand - cand.mean(0), axis=1)))]
    dist = np.linalg.norm(cand - cand[chosen[0]], axis=1)
    while len(chosen) < count:
        k = int(np.argmax(dist))
        chosen.append(k)
        dist = np.minimum(dist, np.linalg.norm(cand - cand[k], axis=1))
    return cand[chosen]


def contour_mask(contour: np.ndarray, size: int) -> np.ndarray:
    """``(size, size)`` bool: the inside of ``contour`` (drawn, then filled from outside: robust to a
    combined contour that crosses itself, as the seed fills it)."""
    img = np.zeros((size + 2, size + 2), np.uint8)
    pts = np.round(contour + 1).astype(np.int32)
    cv2.polylines(img, [pts], True, 255, 1)
    flood = img.copy()
    cv2.floodFill(flood, np.zeros((size + 4, size + 4), np.uint8), (0, 0), 128)
    return (flood != 128)[1:-1, 1:-1]


def transfer(target_simple: np.ndarray, source: Exemplar) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exemplar ``source`` carried into the target whose simplified contour is ``target_simple``:
    ``(premultiplied rgb (S, S, 3) float, alpha (S, S) float 0..1, trunk (S, S) float 0..1)``."""
    s = source.size
    m = warp_map(target_simple, source.simple, (s, s))
    a = source.rgba[..., 3].astype(np.float32) / 255.0
    src = np.dstack([source.rgba[..., :3].astype(np.float32) * a[..., None], a,
                     source.trunk.astype(np.float32)])
    out = cv2.remap(src, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return out[..., :3], out[..., 3], out[..., 4]


def make_variation(exemplars: list[Exemplar], weights: np.ndarray, colour: np.ndarray) -> Variation:
    """The variation of contour ``weights (J,)`` (convex) and colour weights ``colour (J,)`` (convex
    over the exemplars whose contour weight is > 0) — module docstring."""
    w = np.asarray(weights, np.float64)
    size = exemplars[0].size
    contour = np.tensordot(w, np.stack([e.contour for e in exemplars]), 1)
    simple = np.tensordot(w, np.stack([e.simple for e in exemplars]), 1)
    region = contour_mask(contour, size)
    r = max(int(round(DILATE * size)), 1)
    region = cv2.dilate(region.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2)) > 0
    rgb = np.zeros((size, size, 3))
    cw = np.zeros((size, size))
    alpha = np.zeros((size, size))
    trunk = np.zeros((size, size))
    for j, e in enumerate(exemplars):
        if w[j] <= 0:
            continue
        prgb, a, t = transfer(simple, e)
        alpha = np.maximum(alpha, a)
        k = colour[j] * (a > 1e-3)                 # only exemplars that show something here
        rgb += k[..., None] * prgb / np.maximum(a, 1e-3)[..., None]
        cw += k
        trunk += w[j] * t
    rgb = rgb / np.maximum(cw, 1e-9)[..., None]
    alpha = np.where(region, alpha, 0.0)
    rgba = np.dstack([np.clip(rgb, 0, 255), alpha * 255.0]).round().astype(np.uint8)
    return Variation(rgba, (trunk >= 0.5) & (rgba[..., 3] >= ALPHA_T), contour, w, np.asarray(colour, float))


def make_variations(exemplars: list[Exemplar], p: VariationParams | None = None,
                    progress: ProgressFn | None = None) -> list[Variation]:
    """``p.count`` variations of ``exemplars`` (module docstring); one exemplar is given its mirror."""
    p = p or VariationParams()
    ex = list(exemplars)
    if len(ex) == 1:
        ex.append(ex[0].mirrored())
    rng = np.random.default_rng(p.seed)
    weights = spread_weights(len(ex), p.count, rng)
    out = []
    for i, w in enumerate(weights):
        used = w > 0
        colour = np.zeros(len(ex))
        colour[used] = rng.dirichlet(np.ones(int(used.sum())))
        v = make_variation(ex, w, colour)
        v.meta = {"index": i, "exemplars": [e.name for e in ex], "weights": [round(float(x), 6) for x in w],
                  "colour_weights": [round(float(x), 6) for x in colour], "seed": p.seed,
                  "width_over_height": round(v.aspect, 4)}
        out.append(v)
        report(progress, "variations", (i + 1) / len(weights))
    return out


def trunk_polygon_mask(contour: np.ndarray, size: int) -> np.ndarray:
    """``(size, size)`` bool: the trunk a pinned contour bounds (L → B → R, closed along the crown's
    baseline); empty without a trunk."""
    poly = np.concatenate([contour[TRUNK_POINTS + CROWN_POINTS:], contour[:TRUNK_POINTS + 1]])
    img = np.zeros((size, size), np.uint8)
    cv2.fillPoly(img, [np.round(poly).astype(np.int32)], 1)
    return img > 0


#: the variations' files: ``variation_000.png``… and the record of how each was made
IMAGE_NAME = "variation_{:03d}.png"
RECORD = "variations.json"


def planned_files(count: int) -> list[str]:
    """The names a run of ``count`` variations writes in its folder."""
    return [IMAGE_NAME.format(i) for i in range(count)] + [RECORD]


def variation_files(variations: list[Variation], p: VariationParams, sources: list[str]) -> dict[str, bytes]:
    """``{name: bytes}``: each variation as an RGBA PNG (straight alpha) and ``variations.json``
    (the exemplars given, each variation's contour and colour weights over them, its seed, its
    width over height)."""
    from ..fileio import json_bytes
    files: dict[str, bytes] = {}
    for i, v in enumerate(variations):
        ok, buf = cv2.imencode(".png", cv2.cvtColor(v.rgba, cv2.COLOR_RGBA2BGRA))
        if not ok:
            raise RuntimeError("a variation could not be encoded as PNG")
        files[IMAGE_NAME.format(i)] = buf.tobytes()
    doc = {"format": "tree_from_video.variations", "version": 1, "method": "seed 000: convex combinations of "
           "pinned contours (B, R, L; 200 + 1600 + 200 points), RGBA carried by mean value coordinates",
           "exemplars": list(sources), "count": p.count, "size_px": p.size, "seed": p.seed,
           "variations": [dict(v.meta, file=IMAGE_NAME.format(i)) for i, v in enumerate(variations)]}
    files[RECORD] = json_bytes(doc)
    return files
