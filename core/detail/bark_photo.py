"""Bark from photos of bark (issue 36, seed 004 without its GAN): from one or more close-up photos,
a seamless tileable albedo, a height map, a tangent-space normal map and a roughness map, with the
moss and lichen found in the photo by colour and exposed as controls. Pure numpy and OpenCV.

1. **Light**: each photo is divided by its own blur (σ = 1/8 of its shorter side) and multiplied by
   its mean, so the light's gradient across a hand-held photo does not become a brightness seam
   when its patches are laid side by side; the quilted tile likewise, across its own edges
   (σ = 1/12 of the tile, :func:`even_light_torus`).
   A photo larger than two tiles on its shorter side is first shrunk to that
   (:func:`at_tile_scale`): a tile shows half the photo's width of bark.
2. **Height** from the photo's shading (one view has no photogrammetry): the luminance high-passed
   (minus its blur at σ = half a patch: the shading of furrows and plates, not the light) and
   scaled to [0, 1] between its 1st and 99th percentiles; dark crevices low, lit plates high.
   **Several photos of the same bark**: a photo that overlaps another (:mod:`.bark_stereo`, the
   partner with the most matches) takes its height from their parallax where the two see the same
   bark, the shading's elsewhere; ``BarkMaps.height_from`` says which, per photo.
3. **Image quilting** (Efros & Freeman 2001) on a torus: square patches of ``step + overlap``
   texels laid every ``step`` texels in raster order, the tile's last row and column overlapping
   its first (indices modulo the tile), so the tile repeats without a seam. Each patch is picked at
   random among the candidates whose overlap error (Σ over the overlap of the squared colour
   difference, height at half weight) is within ``1 + tol`` of the best, and joined along the
   minimum-error boundary cut of each overlap strip (dynamic programming:
   ``E(i, j) = e(i, j) + min(E(i − 1, j − 1), E(i − 1, j), E(i − 1, j + 1))``, traced back from the
   last row's minimum). Colour and height are quilted together, so the relief stays under its colour.
4. **Normal map** from the height, on the torus: ``n = normalize(−s ∂h/∂u, −s ∂h/∂v, 1)`` with
   ``s = relief_cm / scale_cm · S`` (the height's range is ``relief_cm`` deep; a tile of ``S``
   texels spans ``scale_cm``), stored ``(n + 1) / 2`` as :mod:`.bark_texture`'s.
5. **Roughness**: ``0.6 + 0.35 (1 − h)`` (crevices rougher), moss 0.9.
6. **Moss and lichen by colour** (HSV, OpenCV's 0–180 hue): *moss* is green (hue 30–90, i.e.
   60–180°, saturation ≥ 0.25, value ≥ 0.12); *lichen* is pale and grey (saturation ≤ 0.3, value
   ≥ 0.5 and 0.2 above the bark's median value) or a bright yellow (hue 18–32, i.e. 36–64°,
   saturation ≥ 0.55, value ≥ 0.6 and 0.25 above the bark's median: lit brown bark is orange, hue
   below 18, and darker); each mask opened by 3×3. ``moss`` / ``lichen`` k scale each cover: 0 paints it
   out (OpenCV's Telea inpainting from the bark around it), k < 1 keeps the pixels deepest inside
   it, k > 1 spreads it over the nearest bark, crevices first (the seed's labels put moss in the
   crevices), painted its median colour shaded by the bark's own luminance; cover then ≈ k × the
   photographed cover.

7. **Moss on the branches' upper side**: the branch mesh's UVs put every tube's upper side at
   ``u ≡`` :data:`.branch_mesh.U_UP` (a vertical trunk's north side), so :func:`uv_square` moves the
   tile's moss there over the whole UV square: of its texels the ``n`` (the tile's moss cover) with
   the highest ``up(u) + 0.5 (1 − h) + 0.8 e^(−d/ρ)`` carry moss, ``up(u) = ½ (1 + cos 2π(u − U_UP))``,
   ``d`` the distance to the photographed moss, ``ρ`` a sixteenth of a tile (patches grow from the
   photographed ones, crevices first, on top). Moss left below is painted out (the tile's moss
   inpainted away), moss added is painted as in 6. It is in the texture, so every format carries it.

:func:`bark_maps` is the whole of it; :class:`BarkMaps` what it gives (a
:class:`.bark_texture.BarkTextures` for the writers, and what was measured).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import InputError
from ..params import check, param
from ..progress import ProgressFn, report
from .bark_texture import BarkTextures

#: the smallest photo side (px) bark is taken from: two patches of the default size
MIN_PHOTO_PX = 2 * 80


@dataclass
class BarkPhotoParams:
    """``size`` texels of the tile's side (rounded to whole ``step``\\ s); ``step`` and ``overlap``
    of the quilting's patches (texels of the photo, which is used at its own scale); ``candidates``
    patches tried for each place, ``tol`` how far above the best overlap error a pick may be;
    ``moss``, ``lichen`` their cover (0 none, 1 as photographed, 2 double); ``scale_cm`` the
    tile's side on the tree; ``relief_cm`` the depth between the height's 0 and 1; ``seed``."""

    size: int = param(512, 64, 4096, what="bark tile size", unit="px")
    step: int = param(64, 8, 512, what="bark patch step", unit="px")
    overlap: int = param(16, 2, 256, what="bark patch overlap", unit="px")
    candidates: int = param(200, 1, 5000, what="bark patch candidates")
    tol: float = param(0.1, 0.0, 10.0, what="bark patch tolerance")
    moss: float = param(1.0, 0.0, 2.0, what="--moss")
    lichen: float = param(1.0, 0.0, 2.0, what="--lichen")
    scale_cm: float = param(50.0, 0.0, 10000.0, lo_open=True, what="--bark-scale", unit="cm")
    relief_cm: float = param(1.0, 0.0, 100.0, what="bark relief", unit="cm")
    seed: int = 0


@dataclass
class BarkMaps:
    """The tile (:class:`.bark_texture.BarkTextures`: ``albedo (S, S, 3)`` uint8 sRGB, ``normal``,
    ``height`` in [0, 1]), ``roughness (S, S)`` in [0, 1]; ``moss`` / ``lichen`` cover (share of
    the tile's texels) as photographed (measured on the photos) and in the tile (after the controls);
    ``scale_cm`` the tile's side on the tree; ``neighbour_diff`` the photos' mean colour difference
    of neighbouring pixels (0–255, the yardstick of a seam, :func:`neighbour_difference`);
    ``moss_mask (S, S)`` bool the tile's moss (None: none known, :func:`uv_square` leaves the tile as it is);
    ``height_from`` per photo where its height came from ("shading", or "stereo with photo k: n
    matches, v % of it")."""

    textures: BarkTextures
    roughness: np.ndarray
    moss: tuple[float, float]
    lichen: tuple[float, float]
    scale_cm: float
    neighbour_diff: float
    moss_mask: np.ndarray | None = None
    height_from: tuple[str, ...] = ()


#: the image files a folder of bark photos is read for (:func:`bark_photo_files`)
PHOTO_EXTENSIONS = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".bmp", ".webp")


def bark_photo_files(path: str) -> list[str]:
    """The photos ``path`` names: itself if a file, every image in it (:data:`PHOTO_EXTENSIONS`, by
    name) if a folder: several close-ups of the same bark give its height by parallax
    (:mod:`.bark_stereo`). :class:`InputError` for a path that is neither, or an empty folder."""
    if os.path.isfile(path):
        return [path]
    if not os.path.isdir(path):
        raise InputError(f"bark photo '{path}' does not exist; give a close-up photo of the bark or a folder of them")
    files = sorted(os.path.join(path, n) for n in os.listdir(path) if n.lower().endswith(PHOTO_EXTENSIONS))
    if not files:
        raise InputError(f"the folder '{path}' holds no photo ({', '.join(PHOTO_EXTENSIONS)}); put the "
                         "close-ups of the bark in it or give a photo")
    return files


def read_bark_photo(path: str) -> np.ndarray:
    """The photo ``path`` (BGR uint8), or :class:`InputError` naming why bark cannot be taken from it."""
    img = cv2.imread(path, cv2.IMREAD_COLOR)
    if img is None:
        raise InputError(f"bark photo '{path}' is not a readable image; give a jpg or png of bark")
    if min(img.shape[:2]) < MIN_PHOTO_PX:
        raise InputError(f"bark photo '{path}' is {img.shape[1]}×{img.shape[0]} px; give one at least "
                         f"{MIN_PHOTO_PX} px on its shorter side (a close-up of the bark)")
    if float(img.std()) < 2.0:
        raise InputError(f"bark photo '{path}' is one flat colour; give a close-up of the bark")
    return img


def wide_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """A Gaussian blur of ``img`` at ``sigma`` px, taken on a copy shrunk so that ``sigma`` is 4 px
    there (a blur that wide holds nothing finer; 0.05 s where the full-size blur took 1.3 s)."""
    f = max(1.0, sigma / 4.0)
    if f <= 1.5:
        return cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    h, w = img.shape[:2]
    small = cv2.resize(img, (max(1, int(round(w / f))), max(1, int(round(h / f)))), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma / f, borderType=cv2.BORDER_REFLECT)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def even_light(img: np.ndarray) -> np.ndarray:
    """``img (H, W, 3)`` float32 0–255 divided by its blur (σ = ⅛ of its shorter side) and times its
    mean: the light's gradient removed, the colour kept."""
    f = img.astype(np.float32)
    sigma = min(f.shape[:2]) / 8.0
    low = wide_blur(f, sigma)
    return np.clip(f / np.maximum(low, 1.0) * f.reshape(-1, 3).mean(0), 0.0, 255.0)


def even_light_torus(img: np.ndarray, sigma: float) -> np.ndarray:
    """:func:`even_light` on a tile that repeats: ``img (S, S, 3)`` float32 divided by its blur at
    ``sigma`` taken across its own edges (wrapped), times its mean. Quilting lays like by like,
    so bright and dark patches gather (a tile's halves 12 % apart where the photo's are 3 %); a
    repeated tile would show that as a pattern."""
    pad = int(np.ceil(3 * sigma))
    wrapped = np.pad(img, ((pad, pad), (pad, pad), (0, 0)), mode="wrap")
    low = cv2.GaussianBlur(wrapped, (0, 0), sigma)[pad:-pad, pad:-pad]
    return np.clip(img / np.maximum(low, 1.0) * img.reshape(-1, 3).mean(0), 0.0, 255.0)


def shading_height(img: np.ndarray, sigma: float) -> np.ndarray:
    """``(H, W)`` height in [0, 1] from ``img (H, W, 3)`` BGR float: luminance minus its blur at
    ``sigma`` px, scaled between its 1st and 99th percentiles."""
    lum = img @ np.array([0.114, 0.587, 0.299], np.float32)
    hp = lum - wide_blur(lum, sigma)
    lo, hi = np.percentile(hp, [1.0, 99.0])
    return np.clip((hp - lo) / max(hi - lo, 1e-6), 0.0, 1.0).astype(np.float32)


def min_cut(err: np.ndarray) -> np.ndarray:
    """The minimum-error path down ``err (R, C)``: ``(R,)`` the column of each row, each step
    moving at most one column (module docstring, 3.)."""
    R, C = err.shape
    cost = err.astype(np.float64).copy()
    back = np.zeros((R, C), np.int64)
    cols = np.arange(C)
    for i in range(1, R):                       # one row at a time: a patch's side, not a pixel loop
        prev = cost[i - 1]
        choices = np.stack([np.r_[np.inf, prev[:-1]], prev, np.r_[prev[1:], np.inf]])
        k = np.argmin(choices, axis=0)
        back[i] = cols + k - 1
        cost[i] += choices[k, cols]
    path = np.empty(R, np.int64)
    path[-1] = int(np.argmin(cost[-1]))
    for i in range(R - 1, 0, -1):
        path[i - 1] = back[i, path[i]]
    return path


def _old_side(err: np.ndarray, overlap: int, side: str) -> np.ndarray:
    """``(B, B)`` bool: the texels of a patch on the old (already laid) side of the cut through its
    ``side`` overlap strip ("left", "right", "top", "bottom"), from the error ``err (B, B)``."""
    B = err.shape[0]
    out = np.zeros((B, B), bool)
    idx = np.arange(overlap)
    if side in ("left", "right"):
        strip = err[:, :overlap] if side == "left" else err[:, B - overlap:]
        path = min_cut(strip)
        old = idx[None, :] < path[:, None] if side == "left" else idx[None, :] > path[:, None]
        if side == "left":
            out[:, :overlap] = old
        else:
            out[:, B - overlap:] = old
    else:
        strip = err[:overlap, :] if side == "top" else err[B - overlap:, :]
        path = min_cut(strip.T)
        old = idx[:, None] < path[None, :] if side == "top" else idx[:, None] > path[None, :]
        if side == "top":
            out[:overlap, :] = old
        else:
            out[B - overlap:, :] = old
    return out


def quilt_tileable(src: np.ndarray, n: int, step: int, overlap: int, rng: np.random.Generator,
                   candidates: int = 200, tol: float = 0.1, weights: np.ndarray | None = None,
                   progress: ProgressFn | None = None) -> np.ndarray:
    """A ``(n·step, n·step, C)`` tile quilted from ``src (H, W, C)`` float32 that repeats seamlessly
    (module docstring, 3.); ``weights (C,)`` of each channel in the overlap error."""
    H, W, C = src.shape
    B = step + overlap
    if min(H, W) < B + 1:
        raise InputError(f"the bark photo ({W}×{H} px) is smaller than one patch ({B} px); give a larger photo")
    T = n * step
    w = np.ones(C, np.float32) if weights is None else np.asarray(weights, np.float32)
    used = np.flatnonzero(w > 0)                        # channels that weigh in the error
    canvas = np.zeros((T, T, C), np.float32)
    filled = np.zeros((T, T), bool)
    ar = np.arange(B)
    for k in range(n * n):
        r, c = divmod(k, n)
        report(progress, "bark", k / (n * n))
        rows, cols = (r * step + ar) % T, (c * step + ar) % T
        old = canvas[np.ix_(rows, cols)]
        have = filled[np.ix_(rows, cols)]
        ys = rng.integers(0, H - B + 1, candidates)
        xs = rng.integers(0, W - B + 1, candidates)
        pick = 0
        if have.any():                  # each candidate's error over the texels already laid only
            iy, ix = np.nonzero(have)
            cand = src[ys[:, None] + iy[None], xs[:, None] + ix[None]][..., used]        # (K, n, C')
            score = (((cand - old[iy, ix][None][..., used]) ** 2) * w[used]).sum((1, 2))
            ok = np.flatnonzero(score <= score.min() * (1.0 + tol) + 1e-9)
            pick = int(rng.choice(ok))
        patch = src[ys[pick] + ar[:, None], xs[pick] + ar[None, :]]
        err = (((patch - old) ** 2) * w).sum(-1)
        keep = np.zeros((B, B), bool)
        strips = np.zeros((B, B), bool)
        for side, sl in (("left", (slice(None), slice(0, overlap))), ("right", (slice(None), slice(B - overlap, B))),
                         ("top", (slice(0, overlap), slice(None))), ("bottom", (slice(B - overlap, B), slice(None)))):
            if have[sl].all():                      # a neighbour laid on that side: cut along the best seam
                keep |= _old_side(err, overlap, side)
                strips[sl] = True
        keep = have & (keep | ~strips)
        canvas[np.ix_(rows, cols)] = np.where(keep[..., None], old, patch)
        filled[np.ix_(rows, cols)] = True
    report(progress, "bark", 1.0)
    return canvas


def moss_lichen(bgr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(moss, lichen)`` bool masks ``(H, W)`` of ``bgr`` uint8 by colour (module docstring, 6.)."""
    hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)
    h, s, v = (hsv[..., i].astype(np.float32) for i in range(3))
    s, v = s / 255.0, v / 255.0
    moss = (h >= 30) & (h <= 90) & (s >= 0.25) & (v >= 0.12)
    bark_v = float(np.median(v[~moss])) if (~moss).any() else float(np.median(v))
    lichen = (((s <= 0.3) & (v >= max(0.5, bark_v + 0.2)))
              | ((h >= 18) & (h <= 32) & (s >= 0.55) & (v >= max(0.6, bark_v + 0.25))))
    lichen &= ~moss
    k = np.ones((3, 3), np.uint8)
    return (cv2.morphologyEx(moss.astype(np.uint8), cv2.MORPH_OPEN, k) > 0,
            cv2.morphologyEx(lichen.astype(np.uint8), cv2.MORPH_OPEN, k) > 0)


def scale_cover(albedo: np.ndarray, height: np.ndarray, mask: np.ndarray, k: float,
                others: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(albedo, mask)`` with ``mask``'s cover scaled by ``k`` (module docstring, 6.): 0 inpainted
    away, k < 1 the deepest-inside ``k``·area kept, k > 1 grown over the bark (not over ``others``)
    nearest it, crevices first, to ``k``·area, painted the cover's median colour shaded as the bark."""
    area = int(mask.sum())
    if area == 0 or k == 1.0:
        return albedo, mask
    out = albedo.copy()
    if k < 1.0:
        inside = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, 3)
        want = int(round(k * area))
        order = np.argsort(-inside[mask], kind="stable")
        keep = np.zeros(area, bool)
        keep[order[:want]] = True
        new = np.zeros_like(mask)
        new[mask] = keep
        # the whole cover painted out from the bark around it (not from the cover kept), then the kept
        # part put back
        bare = cv2.inpaint(out, cv2.dilate(mask.astype(np.uint8), np.ones((3, 3), np.uint8)), 5, cv2.INPAINT_TELEA)
        return np.where(new[..., None], out, bare), new
    outside = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, 3)
    cost = outside / max(float(outside.max()), 1.0) + 0.5 * height            # near first, crevices first
    free = ~mask & ~others
    want = min(int(round((k - 1.0) * area)), int(free.sum()))
    order = np.argsort(cost[free], kind="stable")[:want]
    grow = np.zeros(int(free.sum()), bool)
    grow[order] = True
    add = np.zeros_like(mask)
    add[free] = grow
    out[add] = cover_paint(albedo, mask, albedo, add)
    return out, mask | add


def cover_paint(albedo: np.ndarray, mask: np.ndarray, bark: np.ndarray, add: np.ndarray) -> np.ndarray:
    """``(A, 3)`` uint8: the ``add`` texels of new cover, the median colour of ``albedo``'s
    ``mask`` shaded by the luminance of ``bark`` (``(H, W, 3)`` uint8, the bark under them) over
    its median outside ``mask``, the shade within [0.6, 1.4] (module docstring, 6.)."""
    colour = np.median(albedo[mask].astype(np.float32), axis=0)
    lum = bark.astype(np.float32) @ np.array([0.114, 0.587, 0.299], np.float32)
    shade = lum / max(float(np.median(lum[~mask])) if (~mask).any() else 1.0, 1.0)
    return np.clip(colour[None, :] * np.clip(shade[add], 0.6, 1.4)[:, None], 0, 255).astype(np.uint8)


def normal_map(height: np.ndarray, strength: float) -> np.ndarray:
    """``(S, S, 3)`` uint8 tangent-space normals of ``height (S, S)`` on the torus (module
    docstring, 4.): ``strength`` = s, texels of rise per unit of height."""
    du = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) * 0.5
    dv = (np.roll(height, -1, axis=0) - np.roll(height, 1, axis=0)) * 0.5
    n = np.stack([-strength * du, -strength * dv, np.ones_like(height)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.clip(np.rint((n + 1.0) * 127.5), 0, 255).astype(np.uint8)


def neighbour_difference(bgr: np.ndarray, stat=np.mean) -> float:
    """``stat`` (mean; or median) over pixels of the mean absolute colour difference (0–255) to the
    right-hand neighbour: a photo's own texture, the yardstick of a seam (a seam's difference is a
    mean, so it is measured against the photo's mean: a noisy photo's median is well below its mean,
    1.6–1.7 × on the test photos, and even the photo's own columns would fail a median's bar)."""
    d = np.abs(bgr[:, 1:].astype(np.float32) - bgr[:, :-1].astype(np.float32)).mean(-1)
    return float(stat(d))


def seam_difference(tile: np.ndarray) -> float:
    """The mean absolute colour difference (0–255) across the tile's own edges, where it repeats:
    its last column against its first and its last row against its first."""
    t = tile.astype(np.float32)
    return float(np.concatenate([np.abs(t[:, -1] - t[:, 0]).mean(-1), np.abs(t[-1] - t[0]).mean(-1)]).mean())


def at_tile_scale(img: np.ndarray, size: int) -> np.ndarray:
    """``img`` shrunk (never enlarged) so its shorter side is two tiles of ``size``: a tile then
    shows half the photo's width of bark, whatever the camera's resolution (a 12 MP close-up's
    patches would otherwise hold a few millimetres of bark each)."""
    short = min(img.shape[:2])
    if short <= 2 * size:
        return img
    f = 2.0 * size / short
    return cv2.resize(img, (int(round(img.shape[1] * f)), int(round(img.shape[0] * f))), interpolation=cv2.INTER_AREA)


def bark_maps(photos: list[np.ndarray], params: BarkPhotoParams | None = None,
              progress: ProgressFn | None = None) -> BarkMaps:
    """The bark tile of ``photos`` (BGR uint8, :func:`read_bark_photo`) as ``params`` says (module
    docstring). Deterministic per seed; cancellable through ``progress``."""
    p = params or BarkPhotoParams()
    check(p)
    if not photos:
        raise InputError("no bark photo given; give one or more close-ups of the bark")
    rng = np.random.default_rng(p.seed)
    stacks, moss0, lichen0, covers = [], 0, 0, 0
    sigma = (p.step + p.overlap) / 2.0
    shrunk = [at_tile_scale(img, p.size) for img in photos]
    heights, height_from = photo_heights(shrunk, sigma, progress)
    for img, height in zip(shrunk, heights):
        lit = even_light(img)
        m, li = moss_lichen(img)
        moss0, lichen0, covers = moss0 + int(m.sum()), lichen0 + int(li.sum()), covers + m.size
        stacks.append(np.dstack([lit, height * 255.0, m * 255.0, li * 255.0]).astype(np.float32))
    src = max(stacks, key=lambda s: s.shape[0] * s.shape[1])         # quilted from the largest photo
    if len(stacks) > 1:                     # several photos: side by side, each at its own scale
        h = min(s.shape[0] for s in stacks)
        src = np.concatenate([s[:h] for s in stacks], axis=1)
    n = max(2, int(round(p.size / p.step)))
    tile = quilt_tileable(src, n, p.step, p.overlap, rng, p.candidates, p.tol,
                          np.array([1, 1, 1, 0.5, 0, 0], np.float32), progress)
    albedo = np.clip(np.rint(even_light_torus(tile[..., :3], tile.shape[0] / 12.0)), 0, 255).astype(np.uint8)
    height = np.clip(tile[..., 3] / 255.0, 0.0, 1.0).astype(np.float32)
    moss, lichen = tile[..., 4] > 127.5, (tile[..., 5] > 127.5) & ~(tile[..., 4] > 127.5)
    albedo, moss = scale_cover(albedo, height, moss, p.moss, lichen)
    albedo, lichen = scale_cover(albedo, height, lichen, p.lichen, moss)
    S = albedo.shape[0]
    roughness = np.where(moss, 0.9, 0.6 + 0.35 * (1.0 - height)).astype(np.float32)
    normal = normal_map(height, p.relief_cm / p.scale_cm * S)
    return BarkMaps(BarkTextures(cv2.cvtColor(albedo, cv2.COLOR_BGR2RGB), normal, height), roughness,
                    (moss0 / covers, float(moss.mean())), (lichen0 / covers, float(lichen.mean())), p.scale_cm,
                    float(np.median([neighbour_difference(img) for img in photos])), moss, height_from)


def photo_heights(photos: list[np.ndarray], sigma: float,
                  progress: ProgressFn | None = None) -> tuple[list[np.ndarray], tuple[str, ...]]:
    """Each photo's height ``(H, W)`` in [0, 1] (module docstring, 2.): from the parallax against
    the overlapping photo with the most matches where they see the same bark, else from its shading;
    and where each came from."""
    from .bark_stereo import features, stereo_height
    heights = [shading_height(even_light(img), sigma) for img in photos]
    if len(photos) < 2:
        return heights, ("shading",) * len(photos)
    feats = [features(img) for img in photos]
    said = []
    for i, img in enumerate(photos):
        best = None
        for j, other in enumerate(photos):
            if j != i:
                report(progress, "bark height", (i * len(photos) + j) / len(photos) ** 2)
                got = stereo_height(img, other, sigma, feats[i], feats[j])
                if got is not None and (best is None or got[2] > best[1][2]):
                    best = (j, got)
        if best is None:
            said.append("shading")
            continue
        j, (h, valid, n) = best
        heights[i] = np.where(valid, h, heights[i]).astype(np.float32)
        said.append(f"stereo with photo {j + 1}: {n} matches, {100 * valid.mean():.0f} % of it")
    return heights, tuple(said)


def uv_repeats(trunk_radius_m: float, scale_cm: float) -> int:
    """How many tiles of ``scale_cm`` go once around a trunk of ``trunk_radius_m`` (at least 1): the
    branch mesh's UV square is one trunk circumference on a side (:mod:`.branch_mesh`)."""
    return max(1, int(round(2.0 * np.pi * float(trunk_radius_m) * 100.0 / float(scale_cm))))


def uv_square(maps: BarkMaps, trunk_radius_m: float, max_px: int = 2048) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """``(albedo (P, P, 3) uint8 sRGB, normal (P, P, 3) uint8, roughness (P, P) float, repeats)``:
    the tile repeated ``repeats`` × ``repeats`` times (:func:`uv_repeats`) over the branch mesh's
    UV square, at most ``max_px`` on a side, so the bark is ``scale_cm`` a tile on the trunk in every
    format (no texture transform: FBX has none); its moss moved to the branches' upper side
    (:func:`moss_on_top`)."""
    k = uv_repeats(trunk_radius_m, maps.scale_cm)
    t = maps.textures
    S = t.albedo.shape[0]
    P = min(max_px, k * S)

    def tiled(a: np.ndarray, interp: int) -> np.ndarray:
        big = np.tile(a, (k, k) + (1,) * (a.ndim - 2))
        return big if big.shape[0] == P else cv2.resize(big, (P, P), interpolation=interp)
    normal = tiled(t.normal, cv2.INTER_AREA).astype(np.float32) / 127.5 - 1.0
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-6)   # unit again after the average
    albedo, rough = tiled(t.albedo, cv2.INTER_AREA), tiled(maps.roughness.astype(np.float32), cv2.INTER_AREA)
    if maps.moss_mask is not None and maps.moss_mask.any():
        mask = maps.moss_mask.astype(bool)
        bare = cv2.inpaint(t.albedo, cv2.dilate(mask.astype(np.uint8), np.ones((3, 3), np.uint8)), 5,
                           cv2.INPAINT_TELEA)
        height = tiled(t.height.astype(np.float32), cv2.INTER_AREA)
        albedo, top = moss_on_top(albedo, tiled(bare, cv2.INTER_AREA),
                                  tiled(mask.astype(np.float32), cv2.INTER_AREA) > 0.5, height, P / (16.0 * k))
        rough = np.where(top, 0.9, 0.6 + 0.35 * (1.0 - height))
    return albedo, np.clip(np.rint((normal + 1.0) * 127.5), 0, 255).astype(np.uint8), rough.astype(np.float32), k


def up_weight(width: int) -> np.ndarray:
    """``(W,)`` ``up(u) = ½ (1 + cos 2π(u − U_UP))`` at the texel centres ``u = (c + ½) / W`` of a
    UV square ``width`` texels wide: 1 on the branches' upper side, 0 underneath."""
    from .branch_mesh import U_UP
    u = (np.arange(width) + 0.5) / width
    return 0.5 * (1.0 + np.cos(2.0 * np.pi * (u - U_UP)))


def moss_on_top(albedo: np.ndarray, bare: np.ndarray, moss: np.ndarray, height: np.ndarray,
                rho: float) -> tuple[np.ndarray, np.ndarray]:
    """``(albedo, moss)`` of the UV square with ``moss``'s cover moved to the upper side (module
    docstring, 7.): ``albedo``, ``bare`` (the same without moss) ``(P, P, 3)`` uint8, ``moss (P, P)``
    bool, ``height (P, P)`` in [0, 1], ``rho`` texels (the reach of a photographed patch)."""
    n = int(moss.sum())
    d = cv2.distanceTransform((~moss).astype(np.uint8), cv2.DIST_L2, 3)
    score = up_weight(moss.shape[1])[None, :] + 0.5 * (1.0 - height) + 0.8 * np.exp(-d / max(rho, 1.0))
    flat = score.ravel()
    top = np.zeros(flat.size, bool)
    if n:
        top[np.argpartition(-flat, n - 1)[:n]] = True
    top = top.reshape(moss.shape)
    out = np.where(moss[..., None], bare, albedo)                   # the moss that is not kept painted out
    keep = top & moss
    out[keep] = albedo[keep]
    add = top & ~moss
    out[add] = cover_paint(albedo, moss, bare, add)
    return out, top


#: the files :func:`write_bark_files` writes
BARK_FILES = ("bark_albedo.png", "bark_normal.png", "bark_roughness.png", "bark_height.png", "bark_moss.png",
              "bark.json")


def write_bark_files(maps: BarkMaps, folder: str, photos: list[str]) -> list[str]:
    """The tile's maps as files in ``folder`` (:data:`BARK_FILES`: albedo sRGB, normal, roughness
    8-bit, height 16-bit PNG, the moss mask 8-bit (255 moss), and ``bark.json``: the photos, the tile's scale, the covers), each
    written atomically; returns their paths."""
    import json

    from ..fileio import atomic_write_bytes

    def png(a: np.ndarray) -> bytes:
        ok, buf = cv2.imencode(".png", a)
        if not ok:
            raise InputError(f"cannot encode the bark maps for {folder}")
        return buf.tobytes()
    t = maps.textures
    data = {"bark_albedo.png": png(cv2.cvtColor(t.albedo, cv2.COLOR_RGB2BGR)),
            "bark_normal.png": png(cv2.cvtColor(t.normal, cv2.COLOR_RGB2BGR)),
            "bark_roughness.png": png(np.clip(np.rint(maps.roughness * 255), 0, 255).astype(np.uint8)),
            "bark_height.png": png(np.clip(np.rint(t.height * 65535), 0, 65535).astype(np.uint16)),
            "bark_moss.png": png((maps.moss_mask if maps.moss_mask is not None
                                  else np.zeros(t.height.shape, bool)).astype(np.uint8) * 255),
            "bark.json": json.dumps({"photos": [str(p) for p in photos], "tile_cm": maps.scale_cm,
                                     "tile_px": int(t.albedo.shape[0]),
                                     "moss_cover": {"photographed": maps.moss[0], "tile": maps.moss[1]},
                                     "lichen_cover": {"photographed": maps.lichen[0], "tile": maps.lichen[1]},
                                     "height_from": list(maps.height_from)},
                                    indent=2).encode("utf-8")}
    paths = []
    for name in BARK_FILES:
        path = os.path.join(folder, name)
        atomic_write_bytes(path, data[name])
        paths.append(path)
    return paths


def read_bark_files(folder: str) -> BarkMaps:
    """The tile :func:`write_bark_files` wrote in ``folder``, read back; :class:`InputError` naming
    a missing or unreadable map."""
    from ..fileio import read_json
    from .bark_texture import BarkTextures

    def img(name: str, flags: int) -> np.ndarray:
        path = os.path.join(folder, name)
        a = cv2.imread(path, flags) if os.path.isfile(path) else None
        if a is None:
            raise InputError(f"the bark map '{path}' is missing or unreadable; write the bark again "
                             "(--bark-image) or drop the species' bark")
        return a
    albedo = cv2.cvtColor(img("bark_albedo.png", cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    normal = cv2.cvtColor(img("bark_normal.png", cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    rough = img("bark_roughness.png", cv2.IMREAD_GRAYSCALE).astype(np.float64) / 255.0
    height = img("bark_height.png", cv2.IMREAD_UNCHANGED).astype(np.float64) / 65535.0
    moss_path = os.path.join(folder, "bark_moss.png")           # absent in a species written before it
    moss_mask = img("bark_moss.png", cv2.IMREAD_GRAYSCALE) > 127 if os.path.isfile(moss_path) else None
    doc = read_json(os.path.join(folder, "bark.json"), f"bark.json in '{folder}'", "write the bark again")
    try:
        moss = (float(doc["moss_cover"]["photographed"]), float(doc["moss_cover"]["tile"]))
        lichen = (float(doc["lichen_cover"]["photographed"]), float(doc["lichen_cover"]["tile"]))
        scale = float(doc["tile_cm"])
    except (KeyError, TypeError, ValueError):
        raise InputError(f"bark.json in '{folder}' is incomplete; write the bark again") from None
    return BarkMaps(BarkTextures(albedo, normal, height), rough, moss, lichen, scale, 0.0, moss_mask)
