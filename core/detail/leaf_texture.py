"""The leaf cards' procedural textures, one per leaf shape (:data:`..tree3d.LeafClusters.shape`):
a broad leaf's blade for clusters and palm fronds' leaflets, and a needle spray for a conifer's
sprays (:func:`.leaf_clusters.spray_template`). ``(size, size, 4)`` float RGBA in [0, 1], row 0 at
the card's stem (v = 0; Blender's image rows run bottom-up), grey shading multiplied by ``tint``
(sRGB; grey 0.85 is the tint itself): the mesh's colour attribute gives each cluster the video's colour on top. No bpy.
"""
from __future__ import annotations

import numpy as np

#: the textures' side, px
TEXTURE_SIZE = 128
#: a needle spray: the needles leave the twig this far apart along it (a share of the card's
#: length), at this angle to it (degrees, toward the tip), and reach at most this share of the
#: card's width to either side; they are this thick (share of the width)
NEEDLE_STEP = 0.028
NEEDLE_ANGLE_DEG = 55.0
NEEDLE_REACH = 0.42
NEEDLE_WIDTH = 0.018


def leaf_pixels(size: int = TEXTURE_SIZE, tint=(1.0, 1.0, 1.0)) -> np.ndarray:
    """One broad leaf: a pointed blade ``|u − ½| < 0.45 sin(π v^0.8)`` in ``tint`` shaded by a
    darker midrib, transparent outside."""
    v, u = np.mgrid[0:size, 0:size].astype(np.float64) / (size - 1)
    half = 0.45 * np.sin(np.pi * np.clip(v, 0, 1) ** 0.8)
    d = np.abs(u - 0.5)
    alpha = np.clip((half - d) * size * 0.5, 0.0, 1.0)
    grey = 0.85 - 0.25 * np.exp(-(d / 0.02) ** 2) * (v < 0.95) - 0.1 * (d / np.maximum(half, 1e-3)) ** 2
    return _rgba(grey, alpha, tint)


def spray_pixels(size: int = TEXTURE_SIZE, tint=(1.0, 1.0, 1.0)) -> np.ndarray:
    """A conifer's needle spray: a twig up the middle (u = ½, from the stem at v = 0 to the tip)
    and needles leaving it on both sides every :data:`NEEDLE_STEP` of its length at
    :data:`NEEDLE_ANGLE_DEG` toward the tip, each reaching :data:`NEEDLE_REACH` of the width
    (shorter over the first quarter and the last 30 % of the twig, ``v_0`` where it leaves it: a
    feather that narrows to its tip), darker toward the twig; transparent between them.

    A pixel at ``x = |u − ½|`` lies on the needle line that left the twig at
    ``v_0 = v − x cot θ`` (θ the needle's angle); the nearest needle leaves at ``k·step``, and the
    pixel's distance to it across the needle is ``|v_0 − k·step| sin θ``."""
    v, u = np.mgrid[0:size, 0:size].astype(np.float64) / (size - 1)
    x = np.abs(u - 0.5)
    theta = np.radians(NEEDLE_ANGLE_DEG)
    v0 = v - x / np.tan(theta)
    k = np.round(v0 / NEEDLE_STEP)
    across = np.abs(v0 - k * NEEDLE_STEP) * np.sin(theta)
    start = np.clip(k * NEEDLE_STEP, 0.0, 1.0)
    reach = NEEDLE_REACH * np.clip(4.0 * start, 0, 1) * np.clip((1.0 - start) / 0.3, 0, 1) * (k * NEEDLE_STEP >= 0.02)
    px = 1.0 / size                                          # one pixel, for the edges' anti-aliasing
    needle = np.clip((NEEDLE_WIDTH / 2 + px / 2 - across) / px, 0, 1) * np.clip((reach - x) / px, 0, 1)
    twig = np.clip((0.012 + px / 2 - x) / px, 0, 1) * (v <= 0.97)
    alpha = np.maximum(needle, twig)
    grey = np.where(twig >= needle, 0.5, 0.85 - 0.3 * np.exp(-x / 0.08))
    return _rgba(grey, alpha, tint)


#: each leaf shape's texture
PIXELS = {"cluster": leaf_pixels, "frond": leaf_pixels, "spray": spray_pixels}


def shape_pixels(shape: str, size: int = TEXTURE_SIZE, tint=(1.0, 1.0, 1.0)) -> np.ndarray:
    """The texture of leaf ``shape`` (:data:`PIXELS`; a broad leaf for any other)."""
    return PIXELS.get(shape, leaf_pixels)(size, tint)


def _rgba(grey: np.ndarray, alpha: np.ndarray, tint) -> np.ndarray:
    rgba = np.stack([grey, grey, grey, alpha], axis=-1)
    rgba[..., :3] = np.clip(rgba[..., :3] / 0.85 * np.asarray(tint, np.float64), 0, 1)
    return rgba.astype(np.float32)
