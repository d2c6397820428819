"""Frame 1's foreground: which pixels inside the outline are the tree (issue 19).

The colour test of :func:`.branch_fit.tree_map` compares every pixel with the background ring
around the outline as a whole. Against the light that fails: the sky above a backlit crown and
the shadowed ground under it are both in the ring, and the dark crown is as near to the ground's
colours as to nothing — a backlit sample lost 23 % of its crown (recall 0.77), another 99 %.
Here a local colour test (each pixel against the ring pixels nearest it in the image,
:func:`local_colour_distance` over a threshold) only seeds a graph cut (``cv2.grabCut``): pixels outside the outline
are background, those inside the test calls background probably background, the rest probably
tree; two Gaussian mixtures (tree, background) learnt from those labels and a smoothness term
between neighbours decide every pixel. Seeded with the whole ring's test, the cut lost that
second crown entirely (IoU 0.01), and with the inside of the outline all "probably tree", a
sparse tree's sky (0.42). The crown is then one region the mixtures explain, while sky seen
through it stays background (IoU with the true mask on the dev samples: backlit 0.72 → 0.92,
palm 0.57 → 0.92, flutter 0.79 → 0.85, front-lit 0.91 → 0.92).

The cut runs on frame 1 scaled so its larger side is at most :data:`MAX_SIDE` px (0.2–0.3 s
there) and the mask is scaled back (a twig thinner than a pixel of that scale may be lost: the
branch fit keeps reading the colour test).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter
from scipy.spatial import cKDTree

from .branch_fit import TreeMap, background_ring, frame_lab, tree_map

#: the graph cut works on frame 1 scaled so its larger side is at most this many px
MAX_SIDE = 640
#: grabCut's iterations (its mixtures re-estimated from its own labels each time)
ITERATIONS = 4
#: OpenCV's random generator is seeded with this before the cut (its k-means start): the tracking's
#: RANSAC leaves it in a state that differs from run to run of the pipeline
GRABCUT_SEED = 0
#: background-ring pixels each pixel is compared with, the nearest in the image
LOCAL_K = 150
#: a cut that marks more than this × the pixels its seeds marked has grown into the background
#: (on the dev samples a good cut keeps 0.90–0.98 of them; a sparse tree's grew to 1.2): then the
#: whole ring's colour test is the foreground
GROWTH_LIMIT = 1.05
#: the nearest-sample colour test is taken to have lost the crown to a ring holding tree colours
#: when it marks less than this share of what :func:`ratio_map` marks (synthetic samples 0.93–1.06,
#: real crowns whose outline crosses foliage or other trees 0.25–0.74)
CONTAMINATED = 0.85
#: the cut adds to its seeds no smooth pixels, less textured than this (:func:`local_texture`: sky
#: and walls ~0–1, foliage 2–4; the cut's additions on the samples: a sparse crown's sky 0.6
#: median, a backlit or hidden crown's leaves 2.2–5.4) ...
ADDED_TEXTURE = 1.5
#: ... in patches (8-connected) of at least this share of the seeds' area: the samples' sky through
#: the crown 1.3–13 % a patch, a storm palm's leaflets 0.6 % (their widths measure the fronds)
SKY_PATCH = 0.01
#: a cut that keeps less than this share of its seeds has collapsed (a thin tree at 160 × 120: 0)
COLLAPSED = 0.3
#: the local test runs at half the cut's size when that leaves at least this many px a side
LOCAL_MIN_SIDE = 160


#: bins of the inside-vs-ring histogram: per CIELAB axis (L 0–100, a and b −100–100) and of the
#: local texture (log2(1 + std of L over 5 × 5 px), 0–5)
RATIO_COLOUR_BINS = 16
RATIO_TEXTURE_BINS = 8
#: σ of the histograms' smoothing (bins) and of the tree-probability map's (px at the cut's size)
RATIO_HIST_SIGMA = 1.0
RATIO_MAP_SIGMA = 1.0


@dataclass
class Foreground:
    """``mask (H, W)`` bool: frame 1's tree pixels inside the outline; ``share`` their share of
    the outline's pixels; ``method`` ``"graph cut"`` or ``"colour"`` (the colour test alone)."""

    mask: np.ndarray
    share: float
    method: str


def local_colour_distance(img: np.ndarray, outline: np.ndarray, k: int = LOCAL_K) -> np.ndarray:
    """``(H, W)`` float32: inside ``outline``, each pixel's CIELAB distance to the nearest in colour
    of the ``k`` background-ring pixels nearest it in the image; 0 outside the outline and
    everywhere when the ring has fewer than ``k`` pixels. Against the light the ring holds sky
    beside the crown and shadowed ground under it: compared with the whole ring a dark crown
    matches the ground; compared with the ring beside it, it does not."""
    h, w = outline.shape
    ry, rx = background_ring(outline)
    out = np.zeros((h, w), np.float32)
    if len(ry) < k:
        return out
    lab = frame_lab(img)
    step = max(1, len(ry) // 4000)                     # at most ~4000 ring samples
    ring_xy = np.stack([rx[::step], ry[::step]], 1).astype(np.float64)
    ring_lab = lab[ry[::step], rx[::step]]
    iy, ix = np.nonzero(outline)
    _, idx = cKDTree(ring_xy).query(np.stack([ix, iy], 1).astype(np.float64), k=min(k, len(ring_xy)), workers=-1)
    n = max(1, 2_000_000 // max(k, 1))                  # chunks of n pixels: (n, k, 3) floats at a time
    px_lab = lab[iy, ix]
    for a in range(0, len(iy), n):
        diff = ring_lab[idx[a:a + n]] - px_lab[a:a + n, None]
        d2 = np.einsum("pkc,pkc->pk", diff, diff)       # squared distances: no square root per pair
        out[iy[a:a + n], ix[a:a + n]] = np.sqrt(d2.min(1))
    return out


def local_texture(lab_l: np.ndarray) -> np.ndarray:
    """``(H, W)`` float32: log2(1 + the standard deviation of CIELAB L over 5 × 5 px): ~0–1 on a
    sky or a wall, 2–4 on foliage whose leaves are a few px."""
    L = np.asarray(lab_l, np.float32)
    m1 = cv2.blur(L, (5, 5))
    m2 = cv2.blur(L * L, (5, 5))
    return np.log2(1.0 + np.sqrt(np.maximum(m2 - m1 * m1, 0.0)))


def ratio_map(img: np.ndarray, outline: np.ndarray) -> np.ndarray | None:
    """``(H, W)`` float32 in [0, 1]: how much likelier each pixel's colour and texture are inside
    ``outline (H, W)`` bool than in the background ring round it, ``h_in / (h_in + h_ring)`` of
    the two normalized, smoothed histograms over (L, a, b, texture) bins. Inside a loose outline
    the sky, wall or field is the ring's (its share there is at most its share in the ring), and
    the crown is the inside's even where the outline cuts through foliage and part of the crown is
    in the ring: a colour test against the *nearest* ring sample then calls all of that foliage
    background (real crowns: tree share 0.00–0.01). None without a ring."""
    ry, rx = background_ring(outline)
    if len(ry) < 50 or not outline.any():
        return None
    lab = frame_lab(img)
    nb, tb = RATIO_COLOUR_BINS, RATIO_TEXTURE_BINS
    lo, span = np.array([0.0, -100.0, -100.0]), np.array([100.0, 200.0, 200.0])
    q = np.clip(((lab - lo) / span * nb).astype(np.int64), 0, nb - 1)
    t = np.clip((local_texture(lab[..., 0]) / 5.0 * tb).astype(np.int64), 0, tb - 1)
    code = ((q[..., 0] * nb + q[..., 1]) * nb + q[..., 2]) * tb + t
    shape = (nb, nb, nb, tb)

    def hist(c: np.ndarray) -> np.ndarray:
        h = np.bincount(c, minlength=int(np.prod(shape))).reshape(shape).astype(np.float64)
        return gaussian_filter(h, RATIO_HIST_SIGMA) / max(len(c), 1)

    h_in, h_ring = hist(code[outline]), hist(code[ry, rx])
    p = (h_in / (h_in + h_ring + 1e-12)).ravel()[code].astype(np.float32)
    return cv2.GaussianBlur(p, (0, 0), RATIO_MAP_SIGMA)


def foreground(frame_bgr: np.ndarray, outline: np.ndarray, tmap: TreeMap | None = None) -> Foreground | None:
    """The tree's pixels in frame 1 (BGR uint8 ``(H, W, 3)``) inside ``outline (H, W)`` bool, see
    the module docstring; ``tmap`` the colour test if already computed. None when the outline
    leaves no background to compare with (it fills the frame). Deterministic: OpenCV's random
    generator (grabCut's k-means) is seeded first."""
    outline = np.asarray(outline, bool)
    h, w = outline.shape
    s = min(1.0, MAX_SIDE / max(h, w))
    small = (max(1, round(w * s)), max(1, round(h * s)))
    img = frame_bgr if s == 1.0 else cv2.resize(frame_bgr, small, interpolation=cv2.INTER_AREA)
    ol = outline if s == 1.0 else cv2.resize(outline.astype(np.uint8), small, interpolation=cv2.INTER_NEAREST) > 0
    if tmap is None:                   # the whole ring's colour test, at the cut's size (a 4K frame's
        tmap = tree_map(img, ol)       # every pixel would cost seconds)
        if tmap is not None and s != 1.0:
            tmap = replace(tmap, dist=cv2.resize(tmap.dist, (w, h), interpolation=cv2.INTER_NEAREST))
    if tmap is None:
        return None
    half = min(img.shape[:2]) >= 2 * LOCAL_MIN_SIDE     # the seeds at half that size (4× fewer pixels)
    if half:
        hs = (img.shape[1] // 2, img.shape[0] // 2)
        dist = local_colour_distance(cv2.resize(img, hs, interpolation=cv2.INTER_AREA),
                                     cv2.resize(ol.astype(np.uint8), hs, interpolation=cv2.INTER_NEAREST) > 0)
        dist = cv2.resize(dist, (img.shape[1], img.shape[0]), interpolation=cv2.INTER_NEAREST) * ol
    else:
        dist = local_colour_distance(img, ol)
    col = dist > tmap.thr
    pm = ratio_map(img, ol)
    rat = np.zeros_like(ol) if pm is None else (pm > 0.5) & ol       # cut size
    seeds, how = col, "graph cut"
    if col.sum() < CONTAMINATED * rat.sum():
        # the ring holds tree-coloured pixels (the outline crosses foliage, other trees beside it):
        # the nearest-sample test loses what the ratio finds; seed the cut with both
        seeds, how = col | rat, "graph cut (texture seeds)"

    def full(m: np.ndarray) -> np.ndarray:
        m = m if s == 1.0 else cv2.resize(m.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
        return m & outline

    def result(m: np.ndarray, method: str) -> Foreground:
        return Foreground(m, float(m.sum() / max(outline.sum(), 1)), method)

    ratio, seeded = full(rat), full(seeds)
    labels = np.where(ol, np.where(seeds, cv2.GC_PR_FGD, cv2.GC_PR_BGD), cv2.GC_BGD).astype(np.uint8)
    if not (labels == cv2.GC_PR_FGD).any() or ol.all():
        return result(seeded, "colour")
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.setRNGSeed(GRABCUT_SEED)
    try:
        cv2.grabCut(np.ascontiguousarray(img), labels, None, bgd, fgd, ITERATIONS, cv2.GC_INIT_WITH_MASK)
    except cv2.error:                  # a degenerate mixture (e.g. one flat colour): the colour test
        return result(seeded, "colour")
    cut = (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)
    # what the cut adds to its seeds in sizeable smooth patches is sky seen through the crown, taken
    # in for lying between branches (a sparse crown's V: 20-32 % of the seeds' area, texture median
    # 0.6); smaller smooth patches are the insides of broad leaves (a palm's leaflets)
    texture = local_texture(cv2.cvtColor(img, cv2.COLOR_BGR2LAB)[..., 0].astype(np.float32) * (100.0 / 255.0))
    smooth = (cut & ~seeds & (texture < ADDED_TEXTURE)).astype(np.uint8)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(smooth, connectivity=8)
    big = np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= SKY_PATCH * seeds.sum()) + 1
    cut &= ~np.isin(lab, big)
    if s != 1.0:
        cut = cv2.resize(cut.astype(np.uint8), (w, h), interpolation=cv2.INTER_LINEAR) > 0
    mask = cut & outline
    if mask.sum() > GROWTH_LIMIT * seeded.sum():
        # the cut grew into the sky (a sparse tree's twigs): the whole ring's colour test, unless
        # it lost most of what the ratio finds (a ring with tree colours in it: real crowns 0.00–0.06)
        glob = tmap.tree & outline
        return result(ratio, "texture ratio") if glob.sum() < 0.5 * ratio.sum() else result(glob, "colour")
    if mask.sum() < COLLAPSED * seeded.sum():       # the mixtures swallowed the crown: its seeds
        return result(seeded, "colour" if seeds is col else "texture ratio")
    return result(mask, how)


def contour_segments(mask: np.ndarray) -> np.ndarray:
    """The outlines of ``mask (H, W)`` bool (its outer edges and the edges of the sky seen through
    it) as line segments ``(2K, 2)`` float32 px, endpoints in pairs: what the overlays draw."""
    contours, _ = cv2.findContours(np.asarray(mask, np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
    segs = [np.stack([c[:, 0], np.roll(c[:, 0], -1, axis=0)], 1).reshape(-1, 2) for c in contours if len(c) > 1]
    return np.concatenate(segs).astype(np.float32) if segs else np.zeros((0, 2), np.float32)
