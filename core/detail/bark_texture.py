"""The bark as images (issue 32, item 3): an albedo and a tangent-space normal map that stand in for
Blender's procedural bark material where a file format carries images only (glTF, FBX: the
procedural bark arrived white in every engine). Pure numpy; the Blender export binds them to the
bark material while it writes.

Both tile the branch mesh's UV square (:mod:`.branch_mesh`: ``u`` once around a tube, ``v`` one
trunk circumference along it): periodic in ``u`` and ``v`` (band-limited noise made in the Fourier
domain, so the seam at ``u`` = 0 and the repeat along ``v`` are invisible). Like the procedural
material (``operators/scene/materials.py``):

* **albedo**: noise of mean ½ between the ramp's dark and light ends (:func:`bark_ramp`: around
  the video's bark colour, dark 0.35 ×, light 1.65 × it in linear RGB), so its mean is the bark's
  colour; stored sRGB;
* **relief**: cells (fine noise) plus, for "smooth" and "rough" bark, furrows along the branch
  (bands across ``u``, their phase wandering along ``v``), at :data:`BARK_LOOK`'s strengths; the
  normal map is its gradient, ``n = normalize(−s ∂h/∂u, −s ∂h/∂v, 1)``, stored as ``(n + 1) / 2``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .albedo import linear_to_srgb, srgb_to_linear

#: bump strength and furrow weight per bark kind (the procedural material's)
BARK_LOOK = {"none": (0.35, 0.0), "smooth": (0.2, 0.15), "rough": (0.6, 0.6)}
#: the bark's colour ramp, dark and light end (linear RGBA), driven by noise of mean ½
BARK_RAMP = ((0.07, 0.055, 0.045, 1.0), (0.33, 0.29, 0.25, 1.0))
#: texels of the baked images on a side (one trunk circumference square)
TEXTURE_SIZE = 512


@dataclass
class BarkTextures:
    """``albedo (S, S, 3)`` uint8 sRGB, ``normal (S, S, 3)`` uint8 tangent-space (``(n + 1) / 2``,
    +Z out of the surface), ``height (S, S)`` float in [0, 1]; row ``i`` is ``v = i / S``, column
    ``j`` is ``u = j / S``."""
    albedo: np.ndarray
    normal: np.ndarray
    height: np.ndarray


def bark_ramp(colour=None) -> tuple:
    """The bark's colour ramp, dark and light end (linear RGBA): :data:`BARK_RAMP`, or for
    ``colour`` (sRGB 0..1, the video's bark albedo) the same ramp scaled so its middle is that
    colour (dark end 0.35 ×, light end 1.65 × it, the default ramp's proportions)."""
    if colour is None:
        return BARK_RAMP
    mid = srgb_to_linear(np.clip(np.asarray(colour, np.float64), 0.0, 1.0))
    dark, light = (np.clip(mid * k, 0.0, 1.0) for k in (0.35, 1.65))
    return (*dark.tolist(), 1.0), (*light.tolist(), 1.0)


def periodic_noise(size: int, cycles: tuple[float, float], rng: np.random.Generator,
                   octaves: int = 4) -> np.ndarray:
    """``(size, size)`` noise in [0, 1], mean ½, periodic on both axes: white noise low-passed in the
    Fourier domain around ``cycles`` (features per tile along ``v`` (rows), ``u`` (columns)), with
    ``octaves`` octaves of halving amplitude (fBm), rescaled to its 1st–99th percentiles."""
    fy = np.fft.fftfreq(size)[:, None] * size          # cycles per tile
    fx = np.fft.fftfreq(size)[None, :] * size
    out = np.zeros((size, size))
    for k in range(octaves):
        cy, cx = cycles[0] * 2 ** k, cycles[1] * 2 ** k
        gain = np.exp(-0.5 * ((fy / cy) ** 2 + (fx / cx) ** 2))
        spectrum = np.fft.fft2(rng.standard_normal((size, size))) * gain
        layer = np.fft.ifft2(spectrum).real
        out += layer / max(layer.std(), 1e-12) * 0.5 ** k
    lo, hi = np.percentile(out, [1, 99])
    return np.clip((out - lo) / max(hi - lo, 1e-12), 0.0, 1.0)


def bark_textures(colour=None, kind: str = "none", size: int = TEXTURE_SIZE, seed: int = 0) -> BarkTextures:
    """The bark's images (see the module docstring) for the bark ``colour`` (sRGB 0..1; None: the
    default ramp) and ``kind`` ("none", "smooth", "rough")."""
    rng = np.random.default_rng(seed)
    strength, furrow = BARK_LOOK.get(kind, BARK_LOOK["none"])
    dark, light = (np.asarray(e[:3], np.float64) for e in bark_ramp(colour))
    tone = periodic_noise(size, (3.0, 8.0), rng)                     # streaks along the branch
    tone += 0.5 - tone.mean()                                        # mean ½: the ramp's middle
    linear = dark + np.clip(tone, 0.0, 1.0)[..., None] * (light - dark)
    albedo = np.round(255.0 * linear_to_srgb(linear)).astype(np.uint8)
    cells = periodic_noise(size, (12.0, 30.0), rng, octaves=2)      # cells stretched along the branch
    height = cells
    if furrow > 0:
        # bands across u (furrows running along v), 8 around the tube, their phase wandering along v
        u = np.arange(size)[None, :] / size
        wander = periodic_noise(size, (3.0, 1.0), rng, octaves=2) - 0.5
        bands = 0.5 + 0.5 * np.sin(2 * np.pi * (8 * u + 0.6 * wander))
        height = (cells + furrow * bands) / (1.0 + furrow)
    # gradient per texel by central differences across the wrap; s scales it to the look's strength
    gu = 0.5 * (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1))
    gv = 0.5 * (np.roll(height, -1, axis=0) - np.roll(height, 1, axis=0))
    s = strength * size / 16.0
    n = np.stack([-s * gu, -s * gv, np.ones_like(height)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    normal = np.round(255.0 * (n + 1.0) / 2.0).astype(np.uint8)
    return BarkTextures(albedo, normal, height.astype(np.float32))
