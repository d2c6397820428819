"""Stage 8 (start) — leaf seeds (paper Appendix B.1).

The Harris points of frame 1 inside the outline become seeds for leaf clusters. They are split in
two halves by intensity — dark seeds go behind the branches, bright ones in front (the shading of
a real crown) — each is attached to its nearest skeleton node, and gets a depth from that node's
3D position toward the back (dark) or the front (bright) of the crown envelope.

From the video, too: corners on bark or far from any twig are dropped, seeds are added where
the crown shows foliage colour but no corner, each cluster moves to the centre of its tuft and is
sized and coloured from frame 1 (:func:`place_leaves`); the clusters' geometry is
:mod:`.leaf_clusters`'.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from ..envelope import Envelope
from ..tree3d import image_to_plane
from .albedo import SceneLight, leaf_colours, scene_light
from .leaf_clusters import (
    BARK_RADIUS_SHARE,
    TREE_PX_CLOSE,
    LeafParams,
    check_leaf_params,
    cluster_axes,
    make_clusters,
)
from .leaf_cover import card_footprint, uncovered_sites
from .tubes import tube_pixels


@dataclass
class LeafSeeds:
    """``pos2d (S, 2)`` frame-1 px; ``intensity (S,)`` grey 0..255; ``dark (S,)`` bool (behind);
    ``node (S,)`` attached skeleton node; ``pos3d (S, 3)`` px in the lift's plane frame."""

    pos2d: np.ndarray
    intensity: np.ndarray
    dark: np.ndarray
    node: np.ndarray
    pos3d: np.ndarray


def pixel_at(points: np.ndarray, shape: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Columns and rows ``(S,)``, ``(S,)`` of the pixels nearest ``points (S, 2)`` px (x, y), clipped
    to an image of ``shape (H, W, ...)``."""
    return (np.clip(np.round(points[:, 0]).astype(int), 0, shape[1] - 1),
            np.clip(np.round(points[:, 1]).astype(int), 0, shape[0] - 1))


def seed_intensity(gray: np.ndarray, points: np.ndarray, radius: float = 2.0) -> np.ndarray:
    """Mean grey level ``(S,)`` around each point ``(S, 2)`` px: a corner sits on an edge, so a
    single pixel says little about the leaf it belongs to."""
    blur = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), radius)
    x, y = pixel_at(points, gray.shape)
    return blur[y, x]


def split_dark_bright(intensity: np.ndarray) -> np.ndarray:
    """``(S,)`` bool, True for the darker half (below the median), as the paper splits seeds."""
    return intensity < np.median(intensity)


def leaf_seeds(points: np.ndarray, gray: np.ndarray, nodes2d: np.ndarray, nodes3d: np.ndarray,
               base_px: np.ndarray, envelope: Envelope, seed: int = 0) -> LeafSeeds:
    """Seeds from frame-1 Harris ``points (S, 2)`` on the grey frame ``gray``; skeleton frame-1
    ``nodes2d (N, 2)`` px and lifted ``nodes3d (N, 3)`` (plane frame, px); depth toward the back of
    the envelope for dark seeds and the front for bright ones, a seeded share of the way (0.3–0.9)
    from the node's depth (clipped into the envelope at the seed) to the envelope's surface."""
    intensity = seed_intensity(gray, points)
    dark = split_dark_bright(intensity)
    _, node = cKDTree(nodes2d).query(points)
    p3 = image_to_plane(points.astype(np.float64), base_px)
    limit = envelope.depth_limit(p3)                       # |y| allowed at the seed's x, z
    p3[:, 1] = depth_toward_edge(nodes3d[node, 1], limit, dark, np.random.default_rng(seed))
    return LeafSeeds(points.astype(np.float32), intensity, dark, node.astype(np.int32), p3.astype(np.float32))


def depth_toward_edge(node_y: np.ndarray, limit: np.ndarray, dark: np.ndarray,
                      rng: np.random.Generator) -> np.ndarray:
    """Depths ``(S,)`` of seeds: from their node's depth ``node_y (S,)`` clipped into ``±limit (S,)``
    (the envelope's half-depth at the seed), a share t ~ U(0.3, 0.9) of the way to the back
    (``+limit``, y grows away from the camera) for ``dark (S,)`` seeds and to the front otherwise:
    y = y0 + t (edge − y0)."""
    y0 = np.clip(node_y, -limit, limit)
    return y0 + rng.uniform(0.3, 0.9, len(y0)) * (np.where(dark, limit, -limit) - y0)


#: the share of a blur's weight that must fall on tree pixels for :func:`sample_colour` to read them
#: there (a lone tree pixel carries 1/(2πσ²) ≈ 0.04 of a σ = 2 px kernel)
TREE_WEIGHT_MIN = 0.05


def sample_colour(bgr: np.ndarray, points: np.ndarray, radius: float = 2.0,
                  tree_px: np.ndarray | None = None) -> np.ndarray:
    """sRGB colours ``(S, 3)`` in 0..1 around ``points (S, 2)`` px of a BGR frame (blurred, so a
    corner on a leaf edge reads the leaf rather than one pixel). With the tree's pixels
    ``tree_px (H, W)`` only those count (a corner on a small tuft does not read the sky around
    it): the Gaussian-weighted mean over tree pixels; a point with no tree pixel near it (less than
    :data:`TREE_WEIGHT_MIN` of the blur's weight: a cluster over a gap of sky in the crown) reads
    the tree pixel nearest it, as blurred over the tree's pixels there (a real photo's young cedar
    in snow: 9 % of its clusters had no tree pixel near, and 2.9 % of all took the sky's blue-grey
    from the plain blur they read before; 0.8 % now)."""
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    out, lost = _blurred_at(bgr, pts, radius, tree_px)
    if tree_px is not None and lost.any():
        near = nearest_pixels(np.asarray(tree_px, bool), pts[lost])
        if near is not None:
            again, still = _blurred_at(bgr, near, radius, tree_px)
            raw = bgr[near[:, 1].astype(int), near[:, 0].astype(int), ::-1] / 255.0
            out[lost] = np.where(still[:, None], raw, again)
    return out


def nearest_pixels(pixels: np.ndarray, points: np.ndarray) -> np.ndarray | None:
    """``(S, 2)`` px (x, y) of the set pixel of ``pixels (H, W)`` bool nearest each of ``points (S, 2)``
    px (exact Euclidean, :func:`scipy.ndimage.distance_transform_edt` over the box holding both);
    None when no pixel is set."""
    from scipy.ndimage import distance_transform_edt
    ys, xs = np.nonzero(pixels)
    if len(xs) == 0:
        return None
    x, y = pixel_at(points, pixels.shape)
    (y0, y1), (x0, x1) = _window(np.r_[ys.min(), ys.max(), y], np.r_[xs.min(), xs.max(), x], 0, pixels.shape)
    iy, ix = distance_transform_edt(~pixels[y0:y1, x0:x1], return_distances=False, return_indices=True)
    return np.stack([ix[y - y0, x - x0] + x0, iy[y - y0, x - x0] + y0], 1).astype(np.float64)


BAND_ROWS = 256      # rows of the frame blurred at a time in sample_colour


def _blurred_at(bgr: np.ndarray, points: np.ndarray, radius: float,
                tree_px: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sample_colour`'s blur: ``(S, 3)`` sRGB at ``points (S, 2)`` px over ``tree_px`` (all
    pixels when None), and ``(S,)`` bool where too little tree lies near (the plain blur there)."""
    x, y = pixel_at(points, bgr.shape)
    lost = np.zeros(len(x), bool)
    if len(x) == 0:
        return np.zeros((0, 3), np.float32), lost
    # the points' bounding box, in bands of rows, each with a margin past the blur's kernel
    # (OpenCV's float kernel spans 4σ): the same values as blurring the whole frame, without float
    # copies of it (six of a 4K frame's were 600 MB)
    margin = int(np.ceil(4 * radius)) + 2
    (y0, y1), (x0, x1) = _window(y, x, margin, bgr.shape[:2])
    out = np.zeros((len(x), 3), np.float32)
    for top in range(y0, y1, BAND_ROWS):
        here = np.flatnonzero((y >= top) & (y < top + BAND_ROWS))
        if len(here) == 0:
            continue
        b0, b1 = max(y0, top - margin), min(y1, top + BAND_ROWS + margin)
        img = bgr[b0:b1, x0:x1].astype(np.float32)
        blur = cv2.GaussianBlur(img, (0, 0), radius)
        if tree_px is not None:
            wgt = np.asarray(tree_px[b0:b1, x0:x1], np.float32)
            num = cv2.GaussianBlur(img * wgt[..., None], (0, 0), radius)
            den = cv2.GaussianBlur(wgt, (0, 0), radius)[..., None]
            blur = np.where(den > TREE_WEIGHT_MIN, num / np.maximum(den, 1e-6), blur)
            lost[here] = den[y[here] - b0, x[here] - x0, 0] <= TREE_WEIGHT_MIN
        out[here] = blur[y[here] - b0, x[here] - x0, ::-1] / 255.0
    return out, lost


def _window(y: np.ndarray, x: np.ndarray, margin: int, shape: tuple) -> tuple[tuple[int, int], tuple[int, int]]:
    """Row and column ranges ``((y0, y1), (x0, x1))`` of the pixels ``y, x`` plus ``margin``,
    clipped to an image of ``shape (H, W, ...)``."""
    return ((max(0, int(y.min()) - margin), min(shape[0], int(y.max()) + margin + 1)),
            (max(0, int(x.min()) - margin), min(shape[1], int(x.max()) + margin + 1)))


def place_leaves(tree, points: np.ndarray, frame_bgr: np.ndarray, base_px: np.ndarray,
                 params: LeafParams | None = None, mask: np.ndarray | None = None,
                 tree_px: np.ndarray | None = None, foreground: np.ndarray | None = None,
                 light: SceneLight | None = None):
    """Leaf clusters for ``tree`` (a :class:`Tree3D` in metres with ``meta["metres_per_px"]`` and,
    if known, ``meta["envelope"]``) from frame-1 Harris ``points (S, 2)`` px on ``frame_bgr``;
    ``base_px`` the trunk base in frame 1 (px). Each kept seed becomes a cluster on the bone of
    its nearest node (in the image plane, twigs included), at a depth toward the back (dark seed)
    or front (bright seed) of the crown, its main axis pointing away from the crown centre.
    Seeds on the trunk or a main limb's tube (see :func:`on_bark`) are corners on bark, not
    foliage, and are dropped. With the outline ``mask (H, W)``,
    a cluster near its edge shrinks so it ends at the edge (the video shows no leaves outside);
    with frame 1's tree pixels ``tree_px (H, W)`` (:func:`.branch_fit.tree_map`) the edge is that
    of the tree's pixels, gaps narrower than ``TREE_PX_CLOSE`` × the cluster radius closed, so a
    tuft on a bare twig stays as small as the video shows it, and each cluster moves to the centre
    of the tree pixels within its radius (:func:`centre_on_pixels`).
    The clusters' colours follow ``params.colour`` (:func:`.albedo.leaf_colours`, the scene's
    ``light``, measured on ``frame_bgr`` and ``mask`` when not given); ``tree.meta["leaf_colour"]``
    records the choice.
    Returns a :class:`LeafClusters` or None when there are no seeds."""
    from ..envelope import envelope_from_meta
    p = params or LeafParams()
    check_leaf_params(p)
    points = np.asarray(points, np.float64).reshape(-1, 2)
    points = points[np.isfinite(points).all(1)]
    if len(points) == 0:
        return None
    rng = np.random.default_rng(p.seed)
    gray = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2GRAY)
    intensity = seed_intensity(gray, points)
    dark = split_dark_bright(intensity)                    # the split is over all seeds, as in the paper
    scale = float(tree.meta.get("metres_per_px", 1.0))
    rest = tree.nodes3d[0].astype(np.float64)
    candidates = np.arange(1, tree.n_nodes) if tree.n_nodes > 1 else np.arange(1)
    allp = image_to_plane(points, np.asarray(base_px, float)) * scale
    foliage = ~on_bark(allp[:, [0, 2]], tree.parents, rest[:, [0, 2]], tree.radius)
    if foliage.any():
        points, dark = points[foliage], dark[foliage]
    points, dark = near_branches(points, dark, tree, base_px, scale)
    if mask is not None and p.fill:
        extra = fill_seeds(points, frame_bgr, np.asarray(mask, bool), 2 * median_spacing(points), p.seed,
                           None if foreground is None else np.asarray(foreground, bool))
        if len(extra):
            ep = image_to_plane(extra.astype(np.float64), np.asarray(base_px, float)) * scale
            extra = extra[~on_bark(ep[:, [0, 2]], tree.parents, rest[:, [0, 2]], tree.radius)]
            # the same median split as the corners: shaded inner crown goes to the back
            dark = np.concatenate([dark, seed_intensity(gray, extra) < np.median(intensity)])
            points = np.concatenate([points, extra.astype(np.float64)])
    n_keep = int(max(1, round(p.density * len(points))))
    if n_keep > p.max_clusters:        # the budget binds: spread it evenly over the crown
        keep = spread_evenly(points, p.max_clusters, rng)
    else:
        keep = np.sort(rng.choice(len(points), n_keep, replace=False))
    pts, dark = points[keep], dark[keep]
    env = envelope_from_meta(tree.meta)
    spread = float(np.abs(rest[:, 1]).max()) + 1e-6        # no envelope: the skeleton's own depth spread
    nodes_kd = cKDTree(rest[candidates][:, [0, 2]])

    def place(px: np.ndarray, dark_px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres ``(S, 3)`` m of clusters at frame-1 ``px (S, 2)`` and their nearest nodes, in
        depth toward the back of the crown (dark) or its front."""
        at = image_to_plane(px.astype(np.float64), np.asarray(base_px, float)) * scale
        near = candidates[nodes_kd.query(at[:, [0, 2]])[1]]
        limit = env.depth_limit(at) if env is not None else np.full(len(at), spread)
        at[:, 1] = depth_toward_edge(rest[near, 1], limit, dark_px, rng)
        return at, near

    pos, node = place(pts, dark)

    if len(pos) > 1:
        spacing = median_spacing(pos[:, [0, 2]])
    else:
        spacing = 0.05 * max(float(np.ptp(rest[:, 2])), 1e-3)
    radius = max(p.coverage * spacing, 1e-4)
    size = np.ones(len(pos), np.float32)
    base = np.asarray(base_px, float)
    bark: np.ndarray | None = None                         # frame 1's pixels of the traced trunk and limbs
    if mask is not None:                                   # end where the foliage ends
        if tree_px is not None:                            # the tree's own pixels in frame 1
            own = np.asarray(tree_px, bool) & np.asarray(mask, bool)
            kr = max(1, int(round(TREE_PX_CLOSE * radius / scale)))       # px
            if foreground is not None:
                fg = np.asarray(foreground, bool) & np.asarray(mask, bool)
                if (own & fg).sum() < SILHOUETTE_SHARE * fg.sum():   # the colour test missed the crown
                    own = fg
            region = cv2.morphologyEx(own.astype(np.uint8), cv2.MORPH_CLOSE,
                                      cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * kr + 1,) * 2)) > 0
            # a corner sits on its tuft's edge: the cluster goes to the tuft's centre
            pts = centre_on_pixels(pts, own, max(1, int(round(radius / scale))))
            pos[:, [0, 2]] = image_to_plane(pts, np.asarray(base_px, float))[:, [0, 2]] * scale
        else:
            region = foliage_region(points, np.asarray(mask, bool), median_spacing(points))
            own = region
        dist = cv2.distanceTransform(region.astype(np.uint8), cv2.DIST_L2, 5)
        size = _size_at(dist, pts, scale, radius)
        bark = bark_pixels(region.shape, tree, base, scale)
        if p.fill:                                         # clusters where the foliage is still bare
            # the foliage's own pixels (not the gaps the closing bridged), bark left out
            target = own & ~bark
            d_own = cv2.distanceTransform(target.astype(np.uint8), cv2.DIST_L2, 5)
            for _ in range(TOP_UP_ROUNDS):
                if len(pts) >= p.max_clusters:
                    break
                cover = card_footprint(region.shape, pos, cluster_axes(pos), size, radius, 0.55 * radius, p.cards,
                                       p.seed, np.asarray(base_px, float), scale)
                new = uncovered_sites(target, cover, radius / scale)[:p.max_clusters - len(pts)]
                if len(new) == 0:
                    break
                ndark = seed_intensity(gray, new) < np.median(intensity)
                npos, nnode = place(new, ndark)
                pts, pos = np.concatenate([pts, new]), np.concatenate([pos, npos])
                node, dark = np.concatenate([node, nnode]), np.concatenate([dark, ndark])
                size = np.concatenate([size, _size_at(d_own, new, scale, radius)])
    leaf_px = tree_px
    if tree_px is not None:            # the foliage's colour: its own pixels (the cut's foreground where
        # the colour test missed the crown, as for the region above), without the traced trunk and limbs
        if bark is None:                                   # no mask: the tree's pixels are its own
            own = np.asarray(tree_px, bool)
            bark = bark_pixels((own.shape[0], own.shape[1]), tree, base, scale)
        leaf_px = own & ~bark
    colour = leaf_colours(sample_colour(frame_bgr, pts, tree_px=leaf_px), p.colour, light or scene_light(frame_bgr, mask),
                          reference=foliage_colour(frame_bgr, pts, leaf_px, mask, radius / scale))
    tree.meta["leaf_colour"] = colour.meta(p.colour)
    return make_clusters(tree, node, pos, colour.colours, dark, radius, p.cards, p.seed, size, p)


def spread_evenly(points: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of about ``n`` of ``points (P, 2)`` px, one per cell of the coarsest square
    grid that has at least ``n`` occupied cells (a random point of each; the cells with most points
    first where there are more cells than ``n``). Where corners crowd on the crown's textured parts a
    random choice under a binding budget leaves its smoother parts bare (a real 1080p crown: 0.33
    of it); an even one covers it."""
    pts = np.asarray(points, np.float64)
    span = max(float(np.ptp(pts[:, 0])), float(np.ptp(pts[:, 1])), 1.0)
    lo, hi = 1.0, span
    for _ in range(30):                                  # bisection on the cell size (px)
        cell = 0.5 * (lo + hi)
        occupied = len(np.unique(np.floor(pts / cell).astype(np.int64), axis=0))
        lo, hi = (cell, hi) if occupied >= n else (lo, cell)
    key = np.floor(pts / lo).astype(np.int64)
    order = rng.permutation(len(pts))
    _, first, counts = np.unique(key[order], axis=0, return_index=True, return_counts=True)
    pick = order[first]
    if len(pick) > n:
        pick = pick[np.argsort(-counts, kind="stable")[:n]]
    return np.sort(pick)


def _size_at(dist_px: np.ndarray, points: np.ndarray, scale: float, radius: float) -> np.ndarray:
    """Clusters' sizes ``(S,)`` relative to the ``radius`` (m) at ``points (S, 2)`` px: the distance
    map ``dist_px (H, W)`` (to where the foliage ends) there, in metres (``scale`` m per px), over
    the radius, within 0.25..1."""
    x, y = pixel_at(points, dist_px.shape)
    return np.clip(dist_px[y, x] * scale / radius, 0.25, 1.0).astype(np.float32)


def foliage_colour(frame_bgr: np.ndarray, points: np.ndarray, tree_px: np.ndarray | None,
                   mask: np.ndarray | None, radius_px: float) -> np.ndarray | None:
    """sRGB ``(3,)`` median colour of frame 1's tree pixels ``tree_px (H, W)`` (inside ``mask``)
    within half a cluster radius ``radius_px`` of the clusters' centres ``points (S, 2)`` px: the
    foliage as the video shows it (bark and sky left out); None without tree pixels there."""
    if tree_px is None or len(points) == 0:
        return None
    own = np.asarray(tree_px, bool) if mask is None else np.asarray(tree_px, bool) & np.asarray(mask, bool)
    near = np.zeros(own.shape, np.uint8)
    xy = np.round(points).astype(np.int32)
    ok = (xy[:, 0] >= 0) & (xy[:, 0] < own.shape[1]) & (xy[:, 1] >= 0) & (xy[:, 1] < own.shape[0])
    near[xy[ok, 1], xy[ok, 0]] = 1
    r = max(1, int(round(0.5 * radius_px)))
    near = cv2.dilate(near, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2)) > 0
    px = frame_bgr[own & near]
    if len(px) < 20:
        return None
    return np.median(px[:, ::-1].astype(np.float64), axis=0) / 255.0


#: rounds of clusters added where the cards leave frame 1's foliage uncovered (leaf_cover)
TOP_UP_ROUNDS = 2

#: when frame 1's colour test finds less than this share of the graph cut's foreground, the crown
#: is a silhouette the colour test cannot see (backlit: 0.2–0.5) and the clusters fill the cut's
#: foreground instead (lit crowns: 0.9 and more, where the colour test's finer edge is kept)
SILHOUETTE_SHARE = 0.7


def centre_on_pixels(points: np.ndarray, pixels: np.ndarray, radius_px: int) -> np.ndarray:
    """Each of ``points (S, 2)`` px moved to the centroid of the ``pixels (H, W)`` bool within
    ``radius_px`` of it (a disk); a point with none of them stays. A Harris corner lies on the
    edge of the tuft it stands for; the cluster belongs on the tuft's centre."""
    pts = np.asarray(points, np.float64)
    if len(pts) == 0:
        return pts
    h, w = pixels.shape
    x, y = pixel_at(pts, (h, w))
    # the points' bounding box plus the disk: every disk lies inside it (the same sums as on the
    # whole frame, zero outside the frame as before)
    (y0, y1), (x0, x1) = _window(y, x, radius_px + 1, (h, w))
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius_px + 1,) * 2).astype(np.float32)
    img = pixels[y0:y1, x0:x1].astype(np.float32)
    # Σ over the disk of 1, x and y: correlation with the (symmetric) disk, zero outside the frame
    n, sx, sy = (cv2.filter2D(a, cv2.CV_32F, disk, borderType=cv2.BORDER_CONSTANT)
                 for a in (img, img * np.arange(x0, x1, dtype=np.float32)[None, :],
                           img * np.arange(y0, y1, dtype=np.float32)[:, None]))
    x, y = x - x0, y - y0
    cnt = n[y, x].astype(np.float64)
    ok = cnt > 0.5
    out = pts.copy()
    out[ok, 0] = sx[y[ok], x[ok]] / cnt[ok]
    out[ok, 1] = sy[y[ok], x[ok]] / cnt[ok]
    return out


#: Seeds farther than this share of the tree height from every thin branch node are not foliage
#: (grass or shrubs inside a loose outline by the trunk base).
MAX_LEAF_REACH = 0.12


def near_branches(points: np.ndarray, dark: np.ndarray, tree, base_px, scale: float):
    """Keep the seeds ``points (S, 2)`` px (and their ``dark`` flags) within ``MAX_LEAF_REACH`` of
    the tree's height from a node of a thin branch (radius below ``BARK_RADIUS_SHARE`` of the
    trunk's) in the image plane: leaves grow on twigs."""
    r = np.asarray(tree.radius, np.float64)
    thin = np.flatnonzero(r < BARK_RADIUS_SHARE * r.max())
    if len(thin) == 0 or len(points) == 0:
        return points, dark
    rest = tree.nodes3d[0].astype(np.float64)
    height = max(float(np.ptp(rest[:, 2])), 1e-9)
    p = image_to_plane(np.asarray(points, np.float64), np.asarray(base_px, float)) * scale
    d, _ = cKDTree(rest[thin][:, [0, 2]]).query(p[:, [0, 2]])
    keep = d <= MAX_LEAF_REACH * height
    return (points[keep], dark[keep]) if keep.any() else (points, dark)


def bark_pixels(shape: tuple[int, int], tree, base_px: np.ndarray, scale: float, margin: float = 1.5) -> np.ndarray:
    """``(H, W)`` bool: frame 1's pixels within ``margin`` × the radius of a thick branch's axis
    (radius ≥ ``BARK_RADIUS_SHARE`` of the trunk's), the image-space twin of :func:`on_bark`;
    ``scale`` metres per px."""
    from ..tree3d import plane_to_image
    px = plane_to_image(tree.nodes3d[0].astype(np.float64) / scale, base_px)
    return tube_pixels(shape, tree.parents, px, np.asarray(tree.radius, np.float64) / scale,
                       BARK_RADIUS_SHARE, 2 * margin)


def on_bark(points: np.ndarray, parents: np.ndarray, nodes: np.ndarray, radius: np.ndarray,
            margin: float = 1.5) -> np.ndarray:
    """``(S,)`` bool: the image-plane point ``points (S, 2)`` lies within ``margin`` × the branch
    radius of a thick branch's axis (``nodes (N, 2)``, ``radius (N,)`` in the same units; thick:
    radius ≥ ``BARK_RADIUS_SHARE`` of the largest)."""
    from ..topology import edges_of
    edges = edges_of(parents)
    r = np.asarray(radius, np.float64)
    thick = r[edges[:, 1]] >= BARK_RADIUS_SHARE * r.max()     # a branch is as thick as its child end
    e = edges[thick]
    if len(e) == 0 or len(points) == 0:
        return np.zeros(len(points), bool)
    a, b = nodes[e[:, 0]], nodes[e[:, 1]]
    ab = b - a
    t = np.clip(np.einsum("sbk,bk->sb", points[:, None] - a[None], ab) / np.maximum((ab ** 2).sum(1), 1e-12), 0, 1)
    d = np.linalg.norm(points[:, None] - (a[None] + t[..., None] * ab[None]), axis=-1)
    return (d <= margin * r[e[:, 1]][None]).any(1)


def fill_seeds(points: np.ndarray, frame_bgr: np.ndarray, mask: np.ndarray, step: float,
               seed: int = 0, tree_px: np.ndarray | None = None) -> np.ndarray:
    """Extra seeds ``(E, 2)`` px where the crown has foliage but no Harris corner (smooth, shaded
    inner crown, a silhouette against the light): grid points ``step`` px apart inside ``mask``,
    farther than ``1.5·step`` from every seed ``points (S, 2)``, on frame 1's foreground
    ``tree_px (H, W)`` (:mod:`..reconstruct.foreground`) when given, else whose colour (CIELAB)
    is nearer to the seeds' colours than to the background's (pixels outside the outline, near
    it). On a backlit crown the seeds are corners on its edge, half sky, and the colour test
    kept the inner crown out (rendered silhouette IoU 0.45)."""
    h, w = mask.shape
    if len(points) == 0 or not mask.any() or mask.all():
        return np.zeros((0, 2), np.float32)
    step = max(2.0, float(step))
    ys, xs = np.mgrid[step / 2:h:step, step / 2:w:step]
    cand = np.stack([xs.ravel(), ys.ravel()], 1)
    ci = cand.astype(int)
    on = mask[ci[:, 1], ci[:, 0]]
    cand = cand[on & tree_px[ci[:, 1], ci[:, 0]] if tree_px is not None else on]
    if len(cand) == 0:
        return np.zeros((0, 2), np.float32)
    d_seed, _ = cKDTree(points).query(cand)
    cand = cand[d_seed > 1.5 * step]
    if tree_px is not None or len(cand) == 0:   # the foreground says where the foliage is
        return cand.astype(np.float32)
    lab = cv2.cvtColor(cv2.GaussianBlur(frame_bgr, (0, 0), 1.5), cv2.COLOR_BGR2LAB)   # uint8; float where sampled
    rng = np.random.default_rng(seed)
    k = int(max(h, w) * 0.05)        # one square dilation: the same as k 3×3 ones, at the cost of one
    near = cv2.dilate(mask.astype(np.uint8), np.ones((2 * k + 1, 2 * k + 1), np.uint8)) > 0
    by, bx = np.nonzero(near & ~mask)
    if len(by) == 0:
        return np.zeros((0, 2), np.float32)
    pick = rng.choice(len(by), min(4000, len(by)), replace=False)
    bg = lab[by[pick], bx[pick]].astype(np.float32)
    px, py = pixel_at(points, (h, w))
    fg = lab[py, px].astype(np.float32)
    ci = cand.astype(int)
    c = lab[ci[:, 1], ci[:, 0]].astype(np.float32)
    d_fg, _ = cKDTree(fg).query(c)
    d_bg, _ = cKDTree(bg).query(c)
    return cand[d_fg < d_bg].astype(np.float32)


def median_spacing(points: np.ndarray) -> float:
    """Median distance from each point ``(S, 2)`` to its nearest neighbour (1 for < 2 points)."""
    if len(points) < 2:
        return 1.0
    d, _ = cKDTree(points).query(points, k=2)
    return float(np.median(d[:, 1]))


def foliage_region(points: np.ndarray, mask: np.ndarray, spacing_px: float) -> np.ndarray:
    """Where the video shows foliage: ``(H, W)`` bool, disks of ``spacing_px`` around the seed
    ``points (S, 2)`` px, closed over gaps of twice that, holes filled, within the outline
    ``mask``."""
    r = max(1, int(round(spacing_px)))
    region = np.zeros(mask.shape, np.uint8)
    xy = np.round(points).astype(np.int32)
    ok = (xy[:, 0] >= 0) & (xy[:, 0] < mask.shape[1]) & (xy[:, 1] >= 0) & (xy[:, 1] < mask.shape[0])
    region[xy[ok, 1], xy[ok, 0]] = 1
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    region = cv2.dilate(region, disk)
    region = cv2.morphologyEx(region, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (4 * r + 1, 4 * r + 1)))
    contours, _ = cv2.findContours(region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    cv2.drawContours(region, contours, -1, 1, thickness=cv2.FILLED)       # gaps inside the crown
    return (region > 0) & mask
