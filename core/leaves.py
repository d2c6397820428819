"""Stage 8 (start) — leaf seeds (paper Appendix B.1).

The Harris points of frame 1 inside the outline become seeds for leaf clusters. They are split in
two halves by intensity — dark seeds go behind the branches, bright ones in front (the shading of
a real crown) — each is attached to its nearest skeleton node, and gets a depth from that node's
3D position toward the back (dark) or the front (bright) of the crown envelope.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from .lift3d import Envelope
from .tree3d import image_to_plane


@dataclass
class LeafSeeds:
    """``pos2d (S, 2)`` frame-1 px; ``intensity (S,)`` grey 0..255; ``dark (S,)`` bool (behind);
    ``node (S,)`` attached skeleton node; ``pos3d (S, 3)`` px in the lift's plane frame."""

    pos2d: np.ndarray
    intensity: np.ndarray
    dark: np.ndarray
    node: np.ndarray
    pos3d: np.ndarray


def seed_intensity(gray: np.ndarray, points: np.ndarray, radius: float = 2.0) -> np.ndarray:
    """Mean grey level ``(S,)`` around each point ``(S, 2)`` px: a corner sits on an edge, so a
    single pixel says little about the leaf it belongs to."""
    blur = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), radius)
    x = np.clip(np.round(points[:, 0]).astype(int), 0, gray.shape[1] - 1)
    y = np.clip(np.round(points[:, 1]).astype(int), 0, gray.shape[0] - 1)
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
    y0 = np.clip(nodes3d[node, 1], -limit, limit)          # the node's depth, kept inside Ω
    edge = np.where(dark, limit, -limit)                   # y grows away from the camera: back
    t = np.random.default_rng(seed).uniform(0.3, 0.9, len(points))
    p3[:, 1] = y0 + t * (edge - y0)
    return LeafSeeds(points.astype(np.float32), intensity, dark, node.astype(np.int32), p3.astype(np.float32))


# ----------------------------------------------------------------------------- leaf clusters

#: Gaps in frame 1's tree pixels narrower than this share of a cluster's radius are closed before
#: sizing clusters (one cluster covers many leaves and the sky between them).
TREE_PX_CLOSE = 0.5

#: Branches at least this share of the trunk's radius are thick enough for corners on their bark.
BARK_RADIUS_SHARE = 0.3


@dataclass
class LeafParams:
    """Leaf clusters (paper Appendix B.1, §5 "sub-sample the seeds and scale the template").

    ``density`` share of the seeds kept, (0, 1]: fewer clusters, each larger (its radius follows
    the spacing of the kept seeds, so the crown stays covered) — the polygon count is
    ``clusters × cards``; ``max_clusters`` caps the clusters (each is one bone);
    ``cards`` leaf cards (quads) per cluster; ``coverage`` cluster radius as a multiple of the
    median spacing between kept seeds; ``flutter_hz`` ω / 2π; ``flutter_gain`` seconds:
    amplitude A(t) = gain · branch speed(t) / tree height, radians, at most
    ``flutter_max_deg`` (a tracking glitch must not spin a cluster); ``leaf_hz`` / ``leaf_angle_deg`` every leaf's own flap about its stem
    (phase per leaf); ``fill`` adds seeds where the
    crown shows foliage colour but no corner (:func:`fill_seeds`); ``seed`` sub-sampling, depths
    and template."""

    density: float = 1.0
    max_clusters: int = 1200
    cards: int = 16
    coverage: float = 3.0
    flutter_hz: float = 2.0
    flutter_gain: float = 4.0
    flutter_max_deg: float = 35.0
    leaf_hz: float = 4.0
    leaf_angle_deg: float = 15.0
    fill: bool = True
    seed: int = 0


def check_leaf_params(p: LeafParams) -> None:
    from .errors import InputError
    if not 0.0 < p.density <= 1.0:
        raise InputError(f"leaf density {p.density} out of range; use a value in (0, 1]")
    if not 1 <= int(p.cards) <= 256:
        raise InputError(f"{p.cards} leaf cards per cluster; use 1..256")
    if not 1 <= int(p.max_clusters) <= 20000:
        raise InputError(f"{p.max_clusters} leaf clusters; use 1..20000")
    if not (p.flutter_hz >= 0 and p.flutter_gain >= 0 and p.coverage > 0):
        raise InputError("flutter frequency and gain must be ≥ 0 and coverage > 0")


def sample_colour(bgr: np.ndarray, points: np.ndarray, radius: float = 2.0,
                  tree_px: np.ndarray | None = None) -> np.ndarray:
    """sRGB colours ``(S, 3)`` in 0..1 around ``points (S, 2)`` px of a BGR frame (blurred, so a
    corner on a leaf edge reads the leaf rather than one pixel). With the tree's pixels
    ``tree_px (H, W)`` only those count (a corner on a small tuft does not read the sky around
    it): the Gaussian-weighted mean over tree pixels, the plain blur where none is near."""
    img = bgr.astype(np.float32)
    blur = cv2.GaussianBlur(img, (0, 0), radius)
    if tree_px is not None:
        wgt = np.asarray(tree_px, np.float32)
        num = cv2.GaussianBlur(img * wgt[..., None], (0, 0), radius)
        den = cv2.GaussianBlur(wgt, (0, 0), radius)[..., None]
        blur = np.where(den > 0.05, num / np.maximum(den, 1e-6), blur)
    x = np.clip(np.round(points[:, 0]).astype(int), 0, bgr.shape[1] - 1)
    y = np.clip(np.round(points[:, 1]).astype(int), 0, bgr.shape[0] - 1)
    return (blur[y, x, ::-1] / 255.0).astype(np.float32)


def node_speed(nodes3d: np.ndarray, fps: float, window_s: float = 0.25) -> np.ndarray:
    """Speed ``(F, N)`` m/s of every node: central differences of ``nodes3d (F, N, 3)`` metres,
    smoothed over ``window_s`` seconds (tracking jitter would otherwise set the flutter)."""
    F = nodes3d.shape[0]
    if F < 2:
        return np.zeros(nodes3d.shape[:2])
    v = np.linalg.norm(np.gradient(nodes3d.astype(np.float64), axis=0), axis=-1) * fps
    k = max(1, int(round(window_s * fps)))
    if k > 1:
        pad = np.pad(v, ((k // 2, k - 1 - k // 2), (0, 0)), mode="edge")
        c = np.cumsum(np.vstack([np.zeros((1, v.shape[1])), pad]), axis=0)
        v = (c[k:] - c[:-k]) / k
    return v


def flutter_angles(tree, node: np.ndarray, beta: np.ndarray, hz: float, gain: float,
                   max_amp: float = np.inf) -> np.ndarray:
    """``(F, S)`` radians: y(t) = A(t) sin(ω t + β), ω = 2π·hz, A(t) = min(gain · |v_node(t)| / H,
    max_amp) (v the cluster's node speed in m/s, H the tree height in m, t = frame / fps s)."""
    from .details import flutter
    height = max(float(np.ptp(tree.nodes3d[0][:, 2])), 1e-6)
    speed = node_speed(tree.nodes3d[:, np.unique(node)], tree.fps)
    col = np.searchsorted(np.unique(node), node)
    t = np.arange(tree.n_frames) / float(tree.fps)
    rel = np.minimum(speed[:, col] / height, max_amp / max(gain, 1e-12))
    return flutter(t[:, None], rel, 2 * np.pi * hz, beta[None], gain).astype(np.float32)


def place_leaves(tree, points: np.ndarray, frame_bgr: np.ndarray, base_px: np.ndarray,
                 params: LeafParams | None = None, mask: np.ndarray | None = None,
                 tree_px: np.ndarray | None = None):
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
    Returns a :class:`LeafClusters` or None when there are no seeds."""
    from .lift3d import envelope_from_meta
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
        extra = fill_seeds(points, frame_bgr, np.asarray(mask, bool), 2 * median_spacing(points), p.seed)
        if len(extra):
            ep = image_to_plane(extra.astype(np.float64), np.asarray(base_px, float)) * scale
            extra = extra[~on_bark(ep[:, [0, 2]], tree.parents, rest[:, [0, 2]], tree.radius)]
            # the same median split as the corners: shaded inner crown goes to the back
            dark = np.concatenate([dark, seed_intensity(gray, extra) < np.median(intensity)])
            points = np.concatenate([points, extra.astype(np.float64)])
    n_keep = int(min(p.max_clusters, max(1, round(p.density * len(points)))))
    keep = np.sort(rng.choice(len(points), n_keep, replace=False))
    pts, dark = points[keep], dark[keep]
    pos = image_to_plane(pts, np.asarray(base_px, float)) * scale
    _, k = cKDTree(rest[candidates][:, [0, 2]]).query(pos[:, [0, 2]])
    node = candidates[k]

    env = envelope_from_meta(tree.meta)
    if env is not None:
        limit = env.depth_limit(pos)
    else:                                                  # no envelope: the skeleton's own depth spread
        limit = np.full(len(pos), float(np.abs(rest[:, 1]).max()) + 1e-6)
    y0 = np.clip(rest[node, 1], -limit, limit)
    edge = np.where(dark, limit, -limit)                   # y away from the camera: dark to the back
    pos[:, 1] = y0 + rng.uniform(0.3, 0.9, len(pos)) * (edge - y0)

    if len(pos) > 1:
        spacing = median_spacing(pos[:, [0, 2]])
    else:
        spacing = 0.05 * max(float(np.ptp(rest[:, 2])), 1e-3)
    radius = max(p.coverage * spacing, 1e-4)
    size = np.ones(len(pos), np.float32)
    if mask is not None:                                   # end where the foliage ends
        if tree_px is not None:                            # the tree's own pixels in frame 1
            own = np.asarray(tree_px, bool) & np.asarray(mask, bool)
            kr = max(1, int(round(TREE_PX_CLOSE * radius / scale)))       # px
            region = cv2.morphologyEx(own.astype(np.uint8), cv2.MORPH_CLOSE,
                                      cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * kr + 1,) * 2)) > 0
            # a corner sits on its tuft's edge: the cluster goes to the tuft's centre
            pts = centre_on_pixels(pts, own, max(1, int(round(radius / scale))))
            pos[:, [0, 2]] = image_to_plane(pts, np.asarray(base_px, float))[:, [0, 2]] * scale
        else:
            region = foliage_region(points, np.asarray(mask, bool), median_spacing(points))
        dist = cv2.distanceTransform(region.astype(np.uint8), cv2.DIST_L2, 5)
        x = np.clip(np.round(pts[:, 0]).astype(int), 0, mask.shape[1] - 1)
        y = np.clip(np.round(pts[:, 1]).astype(int), 0, mask.shape[0] - 1)
        size = np.clip(dist[y, x] * scale / radius, 0.25, 1.0).astype(np.float32)
    return _clusters(tree, node, pos, sample_colour(frame_bgr, pts, tree_px=tree_px), dark, radius, p.cards, p.seed, size, p)


def centre_on_pixels(points: np.ndarray, pixels: np.ndarray, radius_px: int) -> np.ndarray:
    """Each of ``points (S, 2)`` px moved to the centroid of the ``pixels (H, W)`` bool within
    ``radius_px`` of it (a disk); a point with none of them stays. A Harris corner lies on the
    edge of the tuft it stands for; the cluster belongs on the tuft's centre."""
    pts = np.asarray(points, np.float64)
    if len(pts) == 0:
        return pts
    h, w = pixels.shape
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius_px + 1,) * 2).astype(np.float32)
    img = pixels.astype(np.float32)
    # Σ over the disk of 1, x and y: correlation with the (symmetric) disk, zero outside the frame
    n, sx, sy = (cv2.filter2D(a, cv2.CV_32F, disk, borderType=cv2.BORDER_CONSTANT)
                 for a in (img, img * np.arange(w, dtype=np.float32)[None, :],
                           img * np.arange(h, dtype=np.float32)[:, None]))
    x = np.clip(np.round(pts[:, 0]).astype(int), 0, w - 1)
    y = np.clip(np.round(pts[:, 1]).astype(int), 0, h - 1)
    cnt = n[y, x].astype(np.float64)
    ok = cnt > 0.5
    out = pts.copy()
    out[ok, 0] = sx[y[ok], x[ok]] / cnt[ok]
    out[ok, 1] = sy[y[ok], x[ok]] / cnt[ok]
    return out


def _clusters(tree, node: np.ndarray, pos: np.ndarray, colour: np.ndarray, dark: np.ndarray, radius: float,
              cards: int, seed: int, scale, p: LeafParams):
    """:class:`LeafClusters` at ``pos (S, 3)`` on ``node (S,)``, with what every placement shares:
    the main axis pointing away from the clusters' centre, β from the distance to the node
    (clusters further out along a twig lag behind) and the flutter and leaf flap below the
    keyframes' Nyquist frequency."""
    from .tree3d import LeafClusters
    rest = tree.nodes3d[0].astype(np.float64)
    axis = pos - pos.mean(0)
    norm = np.linalg.norm(axis, axis=1, keepdims=True)
    axis = np.where(norm > 1e-9, axis / np.maximum(norm, 1e-12), [0.0, 0.0, 1.0])
    dist = np.linalg.norm(pos - rest[node], axis=1)
    beta = (2 * np.pi * dist / (4 * radius)) % (2 * np.pi)
    nyquist = 0.45 * float(tree.fps)                       # stay below Nyquist of the keyframes
    flut = flutter_angles(tree, node, beta, min(p.flutter_hz, nyquist), p.flutter_gain,
                          np.radians(p.flutter_max_deg))
    return LeafClusters(node.astype(np.int32), pos.astype(np.float32), axis.astype(np.float32),
                        np.asarray(colour, np.float32), np.asarray(dark, bool), flut, float(radius),
                        float(0.55 * radius), int(cards), int(seed), scale, min(p.leaf_hz, nyquist),
                        float(np.radians(p.leaf_angle_deg)))


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


def on_bark(points: np.ndarray, parents: np.ndarray, nodes: np.ndarray, radius: np.ndarray,
            margin: float = 1.5) -> np.ndarray:
    """``(S,)`` bool: the image-plane point ``points (S, 2)`` lies within ``margin`` × the branch
    radius of a thick branch's axis (``nodes (N, 2)``, ``radius (N,)`` in the same units; thick:
    radius ≥ ``BARK_RADIUS_SHARE`` of the largest)."""
    from .skeleton2d import edges_of
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
               seed: int = 0) -> np.ndarray:
    """Extra seeds ``(E, 2)`` px where the crown has foliage but no Harris corner (smooth, shaded
    inner crown): grid points ``step`` px apart inside ``mask``, farther than ``1.5·step`` from
    every seed ``points (S, 2)``, whose colour (CIELAB) is nearer to the seeds' colours than to
    the background's (pixels outside the outline, near it)."""
    h, w = mask.shape
    if len(points) == 0 or not mask.any() or mask.all():
        return np.zeros((0, 2), np.float32)
    step = max(2.0, float(step))
    lab = cv2.cvtColor(cv2.GaussianBlur(frame_bgr, (0, 0), 1.5), cv2.COLOR_BGR2LAB).astype(np.float32)
    ys, xs = np.mgrid[step / 2:h:step, step / 2:w:step]
    cand = np.stack([xs.ravel(), ys.ravel()], 1)
    ci = cand.astype(int)
    cand = cand[mask[ci[:, 1], ci[:, 0]]]
    if len(cand) == 0:
        return np.zeros((0, 2), np.float32)
    d_seed, _ = cKDTree(points).query(cand)
    cand = cand[d_seed > 1.5 * step]
    if len(cand) == 0:
        return np.zeros((0, 2), np.float32)
    rng = np.random.default_rng(seed)
    near = cv2.dilate(mask.astype(np.uint8), np.ones((3, 3), np.uint8), iterations=int(max(h, w) * 0.05)) > 0
    by, bx = np.nonzero(near & ~mask)
    if len(by) == 0:
        return np.zeros((0, 2), np.float32)
    pick = rng.choice(len(by), min(4000, len(by)), replace=False)
    bg = lab[by[pick], bx[pick]]
    pi = np.clip(np.round(points).astype(int), 0, [w - 1, h - 1])
    fg = lab[pi[:, 1], pi[:, 0]]
    ci = cand.astype(int)
    c = lab[ci[:, 1], ci[:, 0]]
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


def cluster_template(cards: int, radius: float, leaf_size: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """One leaf cluster in its bone's frame (Y = the cluster's main axis, origin at its centre):
    ``cards`` quads, each ``leaf_size`` long and 0.6 × as wide, stem at a point inside the
    sphere of ``0.45 radius`` (biased outward), pointing away from the centre; with ``leaf_size`` ≤
    ``0.55 radius`` every card stays within ``radius`` of the centre. Returns ``co (4·cards, 3)``
    metres and ``uv (4·cards, 2)`` (leaf texture: stem at v = 0, tip at v = 1)."""
    rng = np.random.default_rng(seed)
    C = int(cards)
    u = rng.normal(size=(C, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    u[:, 1] = np.abs(u[:, 1]) * 0.8 - 0.2                   # outward half, a little behind
    stem = u * (radius * 0.45 * rng.uniform(0.2, 1.0, (C, 1)) ** (1 / 3))
    # leaf direction: outward-ish with spread; width direction perpendicular to it and to a random vector
    # leaves radiate from the cluster centre (a cluster seen along its axis is still a disk)
    along = u + np.array([0.0, 0.4, 0.0]) + rng.normal(scale=0.3, size=(C, 3))
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    side = np.cross(along, rng.normal(size=(C, 3)))
    side /= np.maximum(np.linalg.norm(side, axis=1, keepdims=True), 1e-9)
    w = 0.3 * leaf_size
    corners = np.stack([stem - side * w, stem + side * w,
                        stem + side * w + along * leaf_size, stem - side * w + along * leaf_size], axis=1)
    uv = np.tile(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]), (C, 1))
    return corners.reshape(-1, 3), uv


def axis_frames(axis: np.ndarray, seed: int = 0) -> np.ndarray:
    """Rotations ``(S, 3, 3)`` whose Y column is ``axis (S, 3)`` (unit) and a random roll about it."""
    rng = np.random.default_rng(seed + 1)
    y = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    ref = np.where(np.abs(y[:, 2:3]) < 0.9, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    x = np.cross(y, ref)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    z = np.cross(x, y)
    a = rng.uniform(0, 2 * np.pi, len(y))[:, None]
    x, z = np.cos(a) * x + np.sin(a) * z, -np.sin(a) * x + np.cos(a) * z
    return np.stack([x, y, z], axis=2)


def leaf_mesh(leaves) -> dict:
    """Rest-pose geometry of all clusters (the template instanced at every cluster):
    ``co (S·4C, 3)`` metres, ``uv (S·4C, 2)``, ``cluster (S·4C,)`` owning cluster per vertex,
    ``colour (S·4C, 3)`` sRGB (the cluster's video colour, ±10 % per card), ``quads`` = S·C."""
    tco, tuv = cluster_template(leaves.cards, leaves.radius, leaves.leaf_size, leaves.seed)
    R = axis_frames(leaves.axis.astype(np.float64), leaves.seed)
    co = leaves.pos[:, None].astype(np.float64) + np.einsum("sij,vj->svi", R, tco) * leaves.scales()[:, None, None]
    S, V = co.shape[:2]
    rng = np.random.default_rng(leaves.seed + 2)
    shade = np.repeat(rng.uniform(0.9, 1.1, (S, V // 4)), 4, axis=1)[..., None]
    colour = np.clip(leaves.colour[:, None] * shade, 0, 1)
    return {"co": co.reshape(-1, 3), "uv": np.tile(tuv, (S, 1)), "cluster": np.repeat(np.arange(S), V),
            "colour": colour.reshape(-1, 3), "quads": S * (V // 4)}


def leaf_centres(tree) -> np.ndarray:
    """Cluster centres ``(F, S, 3)`` metres as the bones carry them: each centre keeps its rest
    offset from its bone's head, rotated by the bone's world pose rotation (flutter turns a
    cluster about its own centre, so it does not move the centre)."""
    from .bones import bone_edges, quat_rotate, world_rotations
    lv = tree.leaves
    q = world_rotations(tree.parents, tree.nodes3d)                     # (F, B, 4)
    bone_of = np.full(tree.n_nodes, -1)
    bone_of[bone_edges(tree.parents)[:, 1]] = np.arange(tree.n_nodes - 1)
    b = bone_of[lv.node]
    head = tree.parents[lv.node]
    offset = lv.pos.astype(np.float64) - tree.nodes3d[0, head].astype(np.float64)
    return tree.nodes3d[:, head].astype(np.float64) + quat_rotate(q[:, b], offset[None])


def grow_leaves(tree, info: dict, density: float = 1.0, seed: int = 0, params: LeafParams | None = None):
    """Leaf clusters for a generated tree (no video): around its thin-branch nodes (radius below
    ``BARK_RADIUS_SHARE`` of the trunk's), ``info["per_node"] × density`` clusters per node, each
    ``info["radius_frac"] / √density`` of the height (the species' own foliage, paper §5: fewer,
    larger clusters), in the species' leaf colour ±8 %, axis away from the crown centre, flutter
    as for a reconstruction. ``info`` is :func:`.pgm.leaf_info` of the source. Returns
    :class:`LeafClusters` or None."""
    p = params or LeafParams()
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x1EAF])
    rest = tree.nodes3d[0].astype(np.float64)
    r = np.asarray(tree.radius, np.float64)
    thin = np.flatnonzero((r < BARK_RADIUS_SHARE * r.max()) & (np.arange(tree.n_nodes) > 0))
    if len(thin) == 0 or density <= 0:
        return None
    H = max(float(np.ptp(rest[:, 2])), 1e-6)
    n = int(min(p.max_clusters, max(1, round(info["per_node"] * density * len(thin)))))
    node = rng.choice(thin, n, replace=n > len(thin))
    radius = float(info["radius_frac"]) * H / np.sqrt(min(max(density, 1e-3), 1.0))
    pos = rest[node] + rng.normal(scale=0.35 * radius, size=(n, 3))
    colour = np.clip(np.asarray(info["colour"], np.float64)[None] * rng.uniform(0.92, 1.08, (n, 1)), 0, 1)
    dark = (pos[:, 1] - pos.mean(0)[1]) > 0                 # behind the crown centre
    return _clusters(tree, node, pos, colour, dark, radius, info["cards"], seed, None, p)


def leaf_flap_offsets(co: np.ndarray, angle: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every leaf's own flap (paper Appendix B.2's per-leaf high-frequency rotation) as two vertex
    offset fields, for shape keys that skinning carries into every export.

    ``co (4Q, 3)`` the leaf cards' rest vertices (:func:`leaf_mesh`: stem vertices 0, 1 then tip
    vertices 2, 3 of each card); each card turns by ``angle`` radians about its stem line (through
    vertices 0 and 1): ``Δ_q`` = rotated − rest (0 on the stem). With a random phase φ_q per card,
    ``offset(t) = Δ_q sin(ωt + φ_q) = C sin(ωt) + S cos(ωt)`` where ``C = Δ cos φ`` and
    ``S = Δ sin φ`` — returned as ``C (4Q, 3)``, ``S (4Q, 3)`` and ``φ (Q,)``. (Linear in Δ:
    exact for the stem, a chord of the arc elsewhere; at 15° the tip's path is 1 % shorter.)"""
    v = np.asarray(co, np.float64).reshape(-1, 4, 3)
    pivot = 0.5 * (v[:, 0] + v[:, 1])
    axis = v[:, 1] - v[:, 0]
    axis /= np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-12)
    r = v - pivot[:, None]
    c, s = np.cos(angle), np.sin(angle)
    k = axis[:, None]
    rot = r * c + np.cross(k, r) * s + k * np.sum(k * r, axis=-1, keepdims=True) * (1 - c)   # Rodrigues
    delta = rot - r
    phase = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0xF1A9]).uniform(0, 2 * np.pi, len(v))
    C = (delta * np.cos(phase)[:, None, None]).reshape(-1, 3)
    S = (delta * np.sin(phase)[:, None, None]).reshape(-1, 3)
    return C, S, phase


def flap_weights(n_frames: int, fps: float, hz: float) -> np.ndarray:
    """``(F, 4)`` shape-key weights (all in [0, 1], as every format keeps them) of the keys
    +C, −C, +S, −S so that their sum is ``C sin(ωt) + S cos(ωt)``, ω = 2π·hz, t = frame / fps."""
    t = np.arange(n_frames) / float(fps)
    sn, cs = np.sin(2 * np.pi * hz * t), np.cos(2 * np.pi * hz * t)
    return np.stack([np.maximum(sn, 0), np.maximum(-sn, 0), np.maximum(cs, 0), np.maximum(-cs, 0)], axis=1)
