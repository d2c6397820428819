"""Leaf colour as albedo, not as the camera saw it (issue 19).

A video shows foliage through the scene's light and the camera's exposure: a crown against an
overcast sky comes out as a nearly black silhouette, a sunlit one as bright as the sky. The leaves
of the 3D tree need the colour of the leaf itself (its albedo), which is what a render lights.

1. **The scene's light** (:func:`scene_light`): an exposure gain that puts the clip's own bright
   end (the 99th percentile of frame 1's luminance, usually sky) at :data:`WHITE_LEVEL`, and a
   white balance from the bright pixels of the background ring around the outline when they are
   nearly neutral (clouds, an overcast sky: max / min channel ≤ :data:`NEUTRAL_RATIO`); a blue
   sky is not white, so it sets no balance.
2. **Corrected colour**: each sampled colour in linear RGB × balance × gain, back to sRGB.
   The foliage's colour is the median of the crown's own pixels near the clusters when known
   (``reference``), else of the clusters' samples; each cluster keeps its sample's deviation
   from that median.
3. **Reliable or not**: the corrected median colour is trusted unless it is *dark* (relative
   luminance, linear, below :data:`MIN_LUMINANCE`), *backlit* (below :data:`SILHOUETTE_RATIO` of
   the background ring's median luminance: a crown a tenth as bright as the sky beside it is
   seen against the light) or *grey* (HSV saturation below :data:`MIN_SATURATION`). Lit green
   foliage is 0.08–0.3 and a third of an overcast sky's luminance; a backlit crown 0.005–0.02,
   a fortieth of it. An autumn maple passes and keeps its red. A colour brighter than any leaf
   (above :data:`MAX_LUMINANCE`: a grey sky taken for white) is scaled down to it, hue kept. In a
   trusted crown a grey cluster (sky through a gap, a glint) and a sky-blue one in a crown that is
   not blue (:func:`sky_tinted`: shade lit by a blue sky) take the crown's colour at their own
   brightness.
4. **Unreliable**: the albedo is a plausible foliage colour instead — the species' own when a
   species supplies one, else :data:`FOLIAGE_SRGB` — with each cluster's brightness relative to
   the median kept within ±:data:`SPREAD`, so the crown is not one flat colour.

Modes (``LeafParams.colour``): ``"albedo"`` (the above, the default), ``"video"`` (the raw
sample), or ``"#RRGGBB"`` (the user's colour, with the clusters' brightness spread).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import cv2
import numpy as np

from .tubes import tube_pixels

#: the leaf-colour modes besides a ``#RRGGBB`` colour
MODES = ("albedo", "video")
HEX = r"#[0-9A-Fa-f]{6}"
#: linear luminance the clip's bright end (p99 of frame 1) is mapped to
WHITE_LEVEL = 0.9
#: exposure gain limits (a dark clip is lifted at most 4×; an over-exposed one lowered to 0.7×)
GAIN_RANGE = (0.7, 4.0)
#: bright background pixels whose max / min channel ratio is at most this are white (clouds)
NEUTRAL_RATIO = 1.25
#: linear relative luminance below which a corrected foliage colour is a silhouette, not albedo
MIN_LUMINANCE = 0.02
#: foliage darker than this share of the background ring's median luminance is seen against the light
SILHOUETTE_RATIO = 0.1
#: linear relative luminance above which a corrected foliage colour is brighter than any leaf (lit
#: green foliage is 0.08–0.3): an exposure set for the crown against a grey sky darker than white
#: (a real 1080p crown: 0.56). The colour is scaled down to it, its hue kept
MAX_LUMINANCE = 0.3
#: HSV saturation below which the corrected colour carries no hue worth keeping
MIN_SATURATION = 0.15
#: HSV hues (degrees) of a blue sky and of what it lights, cyan to violet: no leaf of a crown that is
#: not itself blue has them (green foliage 60–140°, autumn 0–60°, a copper beech 330–360°)
SKY_HUES = (170.0, 270.0)
#: a plausible foliage albedo, sRGB 0..1 (green the largest channel; linear luminance 0.15)
FOLIAGE_SRGB = np.array([0.33, 0.46, 0.18])
#: each cluster's brightness relative to the median, kept within 1 ± this where a colour is chosen
SPREAD = 0.25
_LUMA = np.array([0.2126, 0.7152, 0.0722])


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB 0..1 → linear RGB (the IEC 61966-2-1 curve), any shape."""
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """Linear RGB → sRGB 0..1 (clipped to 0..1 first), any shape."""
    c = np.clip(np.asarray(c, np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def luminance(linear: np.ndarray) -> np.ndarray:
    """Relative luminance ``(...)`` of linear RGB ``(..., 3)`` (Rec. 709 weights)."""
    return np.asarray(linear, np.float64) @ _LUMA


def saturation(srgb: np.ndarray) -> np.ndarray:
    """HSV saturation ``(...)`` of sRGB ``(..., 3)``: (max − min) / max (0 for black)."""
    c = np.asarray(srgb, np.float64)
    hi, lo = c.max(-1), c.min(-1)
    return np.where(hi > 1e-9, (hi - lo) / np.maximum(hi, 1e-9), 0.0)


def hue(srgb: np.ndarray) -> np.ndarray:
    """HSV hue ``(...)`` of sRGB ``(..., 3)`` in degrees 0..360 (red 0, green 120, blue 240; 0 for grey)."""
    c = np.asarray(srgb, np.float64)
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    hi, d = c.max(-1), np.maximum(c.max(-1) - c.min(-1), 1e-12)
    h = np.where(hi == r, ((g - b) / d) % 6.0, np.where(hi == g, (b - r) / d + 2.0, (r - g) / d + 4.0))
    return np.where(c.max(-1) - c.min(-1) > 1e-12, 60.0 * h, 0.0)


def sky_tinted(srgb: np.ndarray, crown: np.ndarray) -> np.ndarray:
    """``(S,)`` bool: clusters ``srgb (S, 3)`` whose hue is the sky's (:data:`SKY_HUES`, saturation at
    least :data:`MIN_SATURATION`) in a crown whose median colour ``crown (3,)`` is not: foliage in
    shade lit by a blue sky, or sky seen between needles (real photos of open conifers against a blue
    sky: 11–23 % of their clusters teal to blue in a crown of hue 68–78°). A glaucous crown (a blue
    spruce) keeps its blue: its median is in the range itself."""
    c = np.asarray(srgb, np.float64).reshape(-1, 3)
    lo, hi = SKY_HUES
    if lo <= float(hue(np.asarray(crown, np.float64))) <= hi:
        return np.zeros(len(c), bool)
    h = hue(c)
    return (h >= lo) & (h <= hi) & (saturation(c) >= MIN_SATURATION)


def parse_hex(value: str) -> np.ndarray | None:
    """``"#RRGGBB"`` → sRGB ``(3,)`` 0..1, or None when ``value`` is not such a colour."""
    if not isinstance(value, str) or not re.fullmatch(HEX, value):
        return None
    return np.array([int(value[i:i + 2], 16) for i in (1, 3, 5)], np.float64) / 255.0


@dataclass
class SceneLight:
    """``gain`` exposure multiplier on linear RGB; ``balance (3,)`` per-channel white-balance gains
    (linear RGB, luminance-preserving; ones when the scene shows nothing white); ``white_ref``
    whether the balance came from a neutral reference; ``ring`` the background ring's median
    linear luminance after the gain (None: unknown)."""

    gain: float = 1.0
    balance: np.ndarray = field(default_factory=lambda: np.ones(3))
    white_ref: bool = False
    ring: float | None = None

    def correct(self, srgb: np.ndarray) -> np.ndarray:
        """sRGB colours ``(..., 3)`` as albedo: linear × balance × gain, back to sRGB (clipped)."""
        return linear_to_srgb(srgb_to_linear(srgb) * self.balance * self.gain)


def scene_light(frame_bgr: np.ndarray, mask: np.ndarray | None = None) -> SceneLight:
    """The exposure and white balance of frame 1 (BGR uint8 ``(H, W, 3)``); ``mask (H, W)`` the
    tree's outline (its ring of background, 2–8 % of the outline's height outside it, is where a
    white reference is looked for). See the module docstring."""
    rgb = srgb_to_linear(frame_bgr[::2, ::2, ::-1].astype(np.float64) / 255.0)
    lum = luminance(rgb)
    p99 = float(np.percentile(lum, 99))
    gain = float(np.clip(WHITE_LEVEL / max(p99, 1e-6), *GAIN_RANGE))
    balance, white, ring_med = np.ones(3), False, None
    if mask is not None and np.asarray(mask).any():
        m = np.asarray(mask, np.uint8)[::2, ::2]
        ys = np.flatnonzero(m.any(1))
        k = max(1, int(0.08 * (ys[-1] - ys[0] + 1)))
        ring = (cv2.dilate(m, np.ones((2 * k + 1, 2 * k + 1), np.uint8)) > 0) & (m == 0)
        if ring.sum() >= 50:
            ring_rgb, ring_lum = rgb[ring], lum[ring]
            ring_med = float(np.median(ring_lum)) * gain
            bright = ring_rgb[ring_lum >= np.percentile(ring_lum, 90)].mean(0)
            if bright.min() > 1e-4 and bright.max() / bright.min() <= NEUTRAL_RATIO:
                balance = luminance(bright) / bright          # white → grey of the same luminance
                white = True
    return SceneLight(gain, balance, white, ring_med)


@dataclass
class LeafColour:
    """The leaf colours a tree gets: ``colours (S, 3)`` sRGB 0..1 per cluster, ``colour (3,)`` their
    median, ``source`` where it came from (``"video"`` the raw sample, ``"albedo"`` the sample
    corrected for the scene's light, ``"foliage"`` a plausible foliage colour in place of an
    unreliable sample, ``"custom"`` the user's), ``why`` the decision in words with its numbers."""

    colours: np.ndarray
    colour: np.ndarray
    source: str
    why: str

    def meta(self, mode: str) -> dict:
        """What ``Tree3D.meta["leaf_colour"]`` records."""
        return {"mode": mode, "colour": [round(float(c), 4) for c in self.colour], "source": self.source,
                "why": self.why}


def _spread(target: np.ndarray, sampled: np.ndarray) -> np.ndarray:
    """``target (3,)`` sRGB per cluster, each scaled (in linear RGB) by its sample's luminance
    relative to the median, within 1 ± :data:`SPREAD`."""
    lum = luminance(srgb_to_linear(sampled))
    rel = np.clip(lum / max(float(np.median(lum)), 1e-6), 1 - SPREAD, 1 + SPREAD)
    return linear_to_srgb(srgb_to_linear(target)[None] * rel[:, None])


def leaf_colours(sampled: np.ndarray, mode: str = "albedo", light: SceneLight | None = None,
                 fallback: np.ndarray | None = None, reference: np.ndarray | None = None) -> LeafColour:
    """The colours of ``sampled (S, 3)`` sRGB clusters (from the video) under ``mode`` (see the module
    docstring); ``light`` the scene's (:func:`scene_light`; None: no correction); ``fallback`` sRGB
    ``(3,)`` the foliage colour for an unreliable sample (default :data:`FOLIAGE_SRGB`);
    ``reference`` sRGB ``(3,)`` the median of the foliage's own pixels (None: the samples')."""
    sampled = np.clip(np.asarray(sampled, np.float64).reshape(-1, 3), 0.0, 1.0)
    if len(sampled) == 0:
        return LeafColour(sampled.astype(np.float32), np.zeros(3), "video", "no clusters")
    custom = parse_hex(mode)
    if custom is not None:
        out = _spread(custom, sampled)
        return LeafColour(out.astype(np.float32), np.median(out, 0), "custom", f"the colour {mode}")
    if mode == "video":
        return LeafColour(sampled.astype(np.float32), np.median(sampled, 0), "video", "the video's colour")
    if mode != "albedo":
        raise ValueError(f"unknown leaf colour mode {mode!r}")
    light = light or SceneLight()
    lin = srgb_to_linear(sampled)
    if reference is not None:           # the samples' deviations around the foliage pixels' median
        ref = srgb_to_linear(np.clip(np.asarray(reference, np.float64), 0, 1))
        lin = lin * (ref / np.maximum(np.median(lin, 0), 1e-6))[None]
    corrected = light.correct(linear_to_srgb(lin))
    med = light.correct(linear_to_srgb(ref)) if reference is not None else np.median(corrected, 0)
    lum, sat = float(luminance(srgb_to_linear(med))), float(saturation(med))
    ring = light.ring
    facts = (f"corrected median luminance {lum:.3f} (at least {MIN_LUMINANCE}"
             + (f" and {SILHOUETTE_RATIO:g} of the background's {ring:.3f}" if ring is not None else "")
             + f"), saturation {sat:.2f} (at least {MIN_SATURATION}); exposure x{light.gain:.2f}"
             + (", white balance from the background" if light.white_ref else ""))
    backlit = ring is not None and lum < SILHOUETTE_RATIO * ring
    faults = [w for w, bad in (("dark", lum < MIN_LUMINANCE), ("backlit", backlit),
                               ("grey", sat < MIN_SATURATION)) if bad]
    if not faults:
        # a grey cluster in a coloured crown sampled sky through a gap or a glint, not a leaf, and a
        # sky-blue one the sky or its light (sky_tinted): the crown's colour at its own brightness (a
        # real 1080p crown: a tenth of its clusters white)
        stray = (saturation(corrected) < MIN_SATURATION) | sky_tinted(corrected, med)
        if stray.any():
            corrected = corrected.copy()
            corrected[stray] = _spread(med, corrected)[stray]
        if lum <= MAX_LUMINANCE:
            return LeafColour(corrected.astype(np.float32), med, "albedo", "the video's colour as albedo: " + facts)
        k = MAX_LUMINANCE / lum            # brighter than any leaf: darker, same chromaticity
        dim = linear_to_srgb(srgb_to_linear(corrected) * k)
        return LeafColour(dim.astype(np.float32), linear_to_srgb(srgb_to_linear(med) * k), "albedo",
                          f"the video's colour as albedo, scaled to luminance {MAX_LUMINANCE} (brighter than any "
                          "leaf: a grey sky set the exposure): " + facts)
    target = np.asarray(FOLIAGE_SRGB if fallback is None else fallback, np.float64)
    out = _spread(target, sampled)
    return LeafColour(out.astype(np.float32), np.median(out, 0), "foliage",
                      f"{' and '.join(faults)} foliage in the video, a plausible foliage colour instead: " + facts)


# ----------------------------------------------------------------------------- bark

#: the bark's albedo where the video's is unreliable, sRGB (the bark material's former ramp mean)
BARK_SRGB = np.array([0.48, 0.45, 0.42])
#: the trunk is sampled along the edges whose child end is at least this share of the widest radius
TRUNK_SHARE = 0.5
#: bark is darker than foliage (lit bark 0.04–0.1 of linear luminance, a seventh to a fifteenth of
#: the sky beside it; a backlit trunk 0.002–0.01): its own dark and silhouette limits
BARK_MIN_LUMINANCE = 0.01
#: bark is brown to grey: its hue (HSV, degrees) within this range, or its saturation below
#: BARK_GREY; a teal or violet "bark" is the scene's coloured light (a dusk sky taken for white)
BARK_HUES = (0.0, 70.0)
BARK_GREY = 0.25
BARK_SILHOUETTE_RATIO = 0.03


def trunk_pixels(shape: tuple[int, int], parents: np.ndarray, nodes_px: np.ndarray,
                 radius_px: np.ndarray, foreground: np.ndarray | None = None) -> np.ndarray:
    """``(H, W)`` bool: the thick branches' tubes in frame 1 — every edge whose child's radius
    ``radius_px (N,)`` is at least :data:`TRUNK_SHARE` of the widest, drawn as a line of that
    width (0.6 × the diameter, so the edge's blur and the sky beside it stay out) between
    ``nodes_px (N, 2)``. With frame 1's ``foreground (H, W)``, only the lower half of the rows
    below the crown (below the lowest row where the foreground is wider than 8 trunk radii),
    when at least 40 pixels are there: a limb inside a dense crown is seen through leaves, and
    sampled the foliage's colour as the bark's (front-lit dense crown: green bark)."""
    tube = tube_pixels(shape, parents, nodes_px, radius_px, TRUNK_SHARE, 1.2)
    r = np.asarray(radius_px, np.float64)
    if not tube.any():
        return tube
    rmax = float(np.nanmax(r))
    if foreground is not None:
        wide = np.flatnonzero(np.asarray(foreground, bool).sum(1) > 8 * rmax)
        if len(wide):
            below = tube & (np.arange(shape[0]) > wide.max())[:, None]
            if below.sum() >= 40:      # its lower half: a crown tapering to a point stays out
                rows = np.flatnonzero(below.any(1))
                return below & (np.arange(shape[0]) >= 0.5 * (rows[0] + rows[-1]))[:, None]
    return tube


def bark_hue(srgb: np.ndarray) -> float:
    """HSV hue of an sRGB ``(3,)`` colour in degrees 0..360 (red 0, yellow 60, green 120, cyan 180)."""
    return float(hue(np.asarray(srgb, np.float64)))


def hidden_bark() -> LeafColour:
    """The bark's colour when the crown hides the trunk (its pixels are foliage): :data:`BARK_SRGB`."""
    return LeafColour(BARK_SRGB[None].astype(np.float32), BARK_SRGB.copy(), "default",
                      "the crown hides the trunk (what is drawn there is foliage): a plausible bark colour")


def bark_colour(frame_bgr: np.ndarray, trunk: np.ndarray, tree_px: np.ndarray | None,
                light: SceneLight | None = None) -> LeafColour:
    """The bark's albedo from frame 1's trunk pixels ``trunk (H, W)`` (:func:`trunk_pixels`, only
    those that are the tree's, ``tree_px``, when known): their median colour corrected for the
    scene's ``light``; where it is dark or backlit (as :func:`leaf_colours` decides, with bark's
    limits :data:`BARK_MIN_LUMINANCE` and :data:`BARK_SILHOUETTE_RATIO`; grey bark is bark)
    :data:`BARK_SRGB`. Returned as a :class:`LeafColour` of one colour."""
    sel = np.asarray(trunk, bool)
    if tree_px is not None and (sel & np.asarray(tree_px, bool)).sum() >= 20:
        sel = sel & np.asarray(tree_px, bool)
    light = light or SceneLight()
    if sel.sum() < 20:
        return LeafColour(BARK_SRGB[None].astype(np.float32), BARK_SRGB.copy(), "default",
                          f"too few trunk pixels in frame 1 ({int(sel.sum())})")
    med = np.median(frame_bgr[sel][:, ::-1].astype(np.float64), axis=0) / 255.0
    col = light.correct(med)
    lum = float(luminance(srgb_to_linear(col)))
    backlit = light.ring is not None and lum < BARK_SILHOUETTE_RATIO * light.ring
    facts = (f"corrected luminance {lum:.3f} (at least {BARK_MIN_LUMINANCE}"
             + (f" and {BARK_SILHOUETTE_RATIO:g} of the background's {light.ring:.3f}" if light.ring is not None else "")
             + f"); exposure x{light.gain:.2f}")
    if lum < BARK_MIN_LUMINANCE or backlit:
        return LeafColour(BARK_SRGB[None].astype(np.float32), BARK_SRGB.copy(), "default",
                          "a dark or backlit trunk in the video, a plausible bark colour instead: " + facts)
    hue = bark_hue(col)
    if float(saturation(col)) >= BARK_GREY and not BARK_HUES[0] <= hue <= BARK_HUES[1]:
        return LeafColour(BARK_SRGB[None].astype(np.float32), BARK_SRGB.copy(), "default",
                          f"the trunk's corrected colour has hue {hue:.0f} deg and saturation {float(saturation(col)):.2f}, "
                          f"no bark's (brown {BARK_HUES[0]:.0f}-{BARK_HUES[1]:.0f} deg, or grey below {BARK_GREY}): "
                          "coloured light; a plausible bark colour instead: " + facts)
    return LeafColour(col[None].astype(np.float32), col, "albedo", "the trunk's colour as albedo: " + facts)
