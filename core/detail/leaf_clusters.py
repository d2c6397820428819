"""Leaf clusters (paper Appendix B.1, §5): the parameters, the geometry every placement shares
(outward axis, phase β, flutter y(t) = A(t) sin(ωt + β), every leaf's own flap), the cluster
template of leaf cards and its mesh. Where the clusters of a reconstructed tree go is read from the
video in :mod:`.leaf_seeds`; a generated tree's grow in :mod:`.grown_leaves`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import check, param
from .albedo import HEX, MODES

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
    ``flutter_max_deg`` (a tracking glitch must not spin a cluster); ``leaf_hz`` / ``leaf_angle_deg``
    every leaf's own flap about its stem (phase per leaf); ``fill`` adds seeds where the
    crown shows foliage colour but no corner (:func:`fill_seeds`); ``colour`` the leaves' colour:
    ``"albedo"`` (the video's, corrected for the scene's light; a plausible foliage colour where
    the video shows a silhouette), ``"video"`` (the raw sample) or ``"#RRGGBB"`` (:mod:`.albedo`);
    ``seed`` sub-sampling, depths and template."""

    density: float = param(1.0, 0.0, 1.0, lo_open=True, what="leaf density")
    max_clusters: int = param(1200, 1, 20000, what="leaf clusters")
    cards: int = param(16, 1, 256, what="leaf cards per cluster")
    coverage: float = param(3.0, 0.0, lo_open=True, what="leaf coverage")
    flutter_hz: float = param(2.0, 0.0, what="flutter frequency", unit="Hz")
    flutter_gain: float = param(4.0, 0.0, what="flutter strength", unit="s")
    flutter_max_deg: float = 35.0
    leaf_hz: float = 4.0
    leaf_angle_deg: float = 15.0
    fill: bool = True
    colour: str = param("albedo", choices=MODES, pattern=HEX, also="#RRGGBB", what="leaf colour")
    seed: int = 0


def check_leaf_params(p: LeafParams) -> None:
    """Raise :class:`InputError` for a leaf setting out of range."""
    check(p)


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
    from .shapes import flutter
    height = max(float(np.ptp(tree.nodes3d[0][:, 2])), 1e-6)
    speed = node_speed(tree.nodes3d[:, np.unique(node)], tree.fps)
    col = np.searchsorted(np.unique(node), node)
    t = np.arange(tree.n_frames) / float(tree.fps)
    rel = np.minimum(speed[:, col] / height, max_amp / max(gain, 1e-12))
    return flutter(t[:, None], rel, 2 * np.pi * hz, beta[None], gain).astype(np.float32)


def cluster_axes(pos: np.ndarray) -> np.ndarray:
    """Clusters' main axes ``(S, 3)``: unit vectors from the clusters' mean centre out to each of
    ``pos (S, 3)`` (up for a cluster at the centre)."""
    axis = pos - pos.mean(0)
    norm = np.linalg.norm(axis, axis=1, keepdims=True)
    return np.where(norm > 1e-9, axis / np.maximum(norm, 1e-12), [0.0, 0.0, 1.0])


def make_clusters(tree, node: np.ndarray, pos: np.ndarray, colour: np.ndarray, dark: np.ndarray, radius: float,
              cards: int, seed: int, scale, p: LeafParams):
    """:class:`LeafClusters` at ``pos (S, 3)`` on ``node (S,)``, with what every placement shares:
    the main axis pointing away from the clusters' centre, β from the distance to the node
    (clusters further out along a twig lag behind) and the flutter and leaf flap below the
    keyframes' Nyquist frequency."""
    from ..tree3d import LeafClusters
    rest = tree.nodes3d[0].astype(np.float64)
    axis = cluster_axes(pos)
    dist = np.linalg.norm(pos - rest[node], axis=1)
    beta = (2 * np.pi * dist / (4 * radius)) % (2 * np.pi)
    nyquist = 0.45 * float(tree.fps)                       # stay below Nyquist of the keyframes
    hz = min(p.flutter_hz, nyquist)
    flut = flutter_angles(tree, node, beta, hz, p.flutter_gain, np.radians(p.flutter_max_deg))
    return LeafClusters(node.astype(np.int32), pos.astype(np.float32), axis.astype(np.float32),
                        np.asarray(colour, np.float32), np.asarray(dark, bool), flut, float(radius),
                        float(0.55 * radius), int(cards), int(seed), scale, min(p.leaf_hz, nyquist),
                        float(np.radians(p.leaf_angle_deg)), flutter_hz=float(hz))


def as_fronds(tree, leaves):
    """A palm's leaves: ``leaves`` (:class:`LeafClusters`) as stretches of frond — shape
    ``"frond"``, each one's axis along the bone that carries it (node − its parent, rest pose), so
    its leaflets line that bone in pairs (:func:`frond_template`). None stays None."""
    import dataclasses
    if leaves is None:
        return None
    axis = _unit_rows(_bone_vectors(tree, leaves.node), 1e-9, [0.0, 0.0, 1.0])
    return dataclasses.replace(leaves, axis=axis.astype(np.float32), shape="frond")


def _bone_vectors(tree, node: np.ndarray) -> np.ndarray:
    """``(S, 3)``: each of ``node``'s bones at rest, the node minus its parent (0 at the root)."""
    rest = tree.nodes3d[0].astype(np.float64)
    return rest[node] - rest[np.maximum(np.asarray(tree.parents)[node], 0)]


def _unit_rows(v: np.ndarray, tol: float, fallback) -> np.ndarray:
    """``v (S, 3)``'s rows as unit vectors; ``fallback`` (a vector, or ``(S, 3)``) where a row's
    length is ``tol`` or less."""
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(n > tol, v / np.maximum(n, 1e-12), fallback)


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


def frond_template(cards: int, radius: float, leaf_size: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A stretch of a palm frond in its bone's frame (Y = the frond's direction, X across it,
    roughly level): ``cards`` leaflets in pairs along Y from ``−radius`` to ``+radius``, stems on
    the midrib, each pointing out to its side and 35° forward, drooping 20°, ``leaf_size`` long
    and 0.25 × as wide (longest mid-stretch). Same layout as :func:`cluster_template`."""
    rng = np.random.default_rng(seed)
    C = int(cards)
    t = (np.arange(C) // 2 + 0.5) / max((C + 1) // 2, 1)              # pairs along the midrib
    side = np.where(np.arange(C) % 2 == 0, 1.0, -1.0)
    stem = np.stack([np.zeros(C), radius * (2 * t - 1), np.zeros(C)], 1)
    fwd, droop = np.radians(35.0), np.radians(20.0)
    along = np.stack([side * np.cos(fwd) * np.cos(droop), np.full(C, np.sin(fwd)), np.full(C, -np.sin(droop))], 1)
    along += rng.normal(scale=0.05, size=(C, 3))
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    width = np.cross(along, np.array([0.0, 0.0, 1.0]))
    width /= np.maximum(np.linalg.norm(width, axis=1, keepdims=True), 1e-9)
    length = leaf_size * (0.6 + 0.4 * np.sin(np.pi * t))[:, None]
    w = 0.125 * length
    corners = np.stack([stem - width * w, stem + width * w,
                        stem + width * w + along * length, stem - width * w + along * length], axis=1)
    uv = np.tile(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]), (C, 1))
    return corners.reshape(-1, 3), uv


def as_sprays(tree, leaves):
    """A conifer's leaves: ``leaves`` (:class:`LeafClusters`) as needle sprays — shape ``"spray"``,
    each one's axis pointing away from the trunk, level (its sprays spread level and droop at their
    tips, :func:`spray_template`; a cluster on the trunk's line points along its bone). None
    stays None."""
    import dataclasses
    if leaves is None:
        return None
    rest = tree.nodes3d[0].astype(np.float64)
    out = leaves.pos.astype(np.float64) - rest[0]
    out[:, 2] = 0.0                                           # level, away from the trunk's foot
    bone = _bone_vectors(tree, leaves.node)
    bone[:, 2] = 0.0
    axis = _unit_rows(out, 1e-6 * max(float(np.ptp(rest[:, 2])), 1e-9), _unit_rows(bone, 1e-12, [1.0, 0.0, 0.0]))
    return dataclasses.replace(leaves, axis=axis.astype(np.float32), shape="spray")


def leaves_for_form(tree, leaves, form: str | None):
    """``leaves`` shaped for the tree's ``form``: a palm's as fronds (:func:`as_fronds`), a
    conifer's as needle sprays (:func:`as_sprays`), any other's as they are (clusters)."""
    return as_fronds(tree, leaves) if form == "palm" else as_sprays(tree, leaves) if form == "conifer" else leaves


def spray_template(cards: int, radius: float, leaf_size: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A conifer's foliage in one cluster, in its bone's frame (Y = away from the trunk, X level
    across it, Z up): ``cards`` needle sprays (:func:`.leaf_texture.spray_pixels`), each fanned up
    to ±35° about Y in its level plane, drooping 5–25° toward its tip and tilted about its own twig
    by up to ±:data:`ROLL_DEG` (listed most tilted first: a level of detail keeping a few cards of
    each cluster keeps those a level camera sees, not sprays edge-on to it); their middles within
    ``0.45 radius`` of the centre (less in depth and height), ``1.1–1.6 leaf_size`` long and 0.44 ×
    as wide (with ``leaf_size`` = ``0.55 radius``, the cluster's own, the ends stay within about
    ``radius``, as a cluster's cards do). Same layout as :func:`cluster_template`."""
    rng = np.random.default_rng(seed)
    C = int(cards)
    fan = rng.uniform(-1.0, 1.0, C) * np.radians(35.0)
    droop = rng.uniform(np.radians(5.0), np.radians(25.0), C)
    along = np.stack([np.sin(fan) * np.cos(droop), np.cos(fan) * np.cos(droop), -np.sin(droop)], 1)
    level = np.stack([np.cos(fan), -np.sin(fan), np.zeros(C)], 1)          # level, across the spray
    roll = rng.uniform(-1.0, 1.0, (C, 1)) * np.radians(ROLL_DEG)             # each spray tilted about itself
    roll = roll[np.argsort(-np.abs(roll[:, 0]))]     # most tilted first: what a LOD keeps (lod.kept_cards)
    width = np.cos(roll) * level + np.sin(roll) * np.cross(along, level)
    length = 1.6 * leaf_size * rng.uniform(0.7, 1.0, (C, 1))
    # the sprays' middles about the centre, as a cluster's leaves are: the crown the clusters fill
    # keeps its edge instead of growing outward by half a spray
    middle = rng.uniform(-0.45, 0.45, (C, 3)) * radius * np.array([1.0, 0.8, 0.6])
    stem = middle - 0.5 * along * length
    w = 0.22 * length
    corners = np.stack([stem - width * w, stem + width * w,
                        stem + width * w + along * length, stem - width * w + along * length], axis=1)
    uv = np.tile(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]), (C, 1))
    return corners.reshape(-1, 3), uv


#: a conifer's sprays are tilted about their own twig by up to this many degrees either way: level
#: sprays are edge-on to a camera level with the crown, and the crown seen from the side would
#: thin out to its layers' edges
ROLL_DEG = 75.0


#: each leaf shape's card layout
TEMPLATES = {"cluster": cluster_template, "frond": frond_template, "spray": spray_template}
#: the shapes whose clusters keep their X axis level (no random roll about their axis)
LEVEL = ("frond", "spray")


def template(shape: str, cards: int, radius: float, leaf_size: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The card layout of one cluster of ``shape`` (:data:`TEMPLATES`; ``"cluster"`` for any other)."""
    return TEMPLATES.get(shape, cluster_template)(cards, radius, leaf_size, seed)


def axis_frames(axis: np.ndarray, seed: int = 0, level: bool = False) -> np.ndarray:
    """Rotations ``(S, 3, 3)`` whose Y column is ``axis (S, 3)`` (unit) and a random roll about it
    (``level``: none, X kept horizontal — a frond's leaflets spread level)."""
    rng = np.random.default_rng(seed + 1)
    y = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    ref = np.where(np.abs(y[:, 2:3]) < 0.9, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    x = np.cross(y, ref)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    z = np.cross(x, y)
    a = rng.uniform(0, 2 * np.pi, len(y))[:, None] * (0.0 if level else 1.0)
    x, z = np.cos(a) * x + np.sin(a) * z, -np.sin(a) * x + np.cos(a) * z
    return np.stack([x, y, z], axis=2)


def leaf_mesh(leaves) -> dict:
    """Rest-pose geometry of all clusters (the template instanced at every cluster):
    ``co (S·4C, 3)`` metres, ``uv (S·4C, 2)``, ``cluster (S·4C,)`` owning cluster per vertex,
    ``colour (S·4C, 3)`` sRGB (the cluster's video colour, ±10 % per card), ``quads`` = S·C."""
    tco, tuv = template(leaves.shape, leaves.cards, leaves.radius, leaves.leaf_size, leaves.seed)
    R = axis_frames(leaves.axis.astype(np.float64), leaves.seed, leaves.shape in LEVEL)
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
    from ..bones import bone_edges, world_rotations
    from ..rotations import quat_rotate
    lv = tree.leaves
    q = world_rotations(tree.parents, tree.nodes3d)                     # (F, B, 4)
    bone_of = np.full(tree.n_nodes, -1)
    bone_of[bone_edges(tree.parents)[:, 1]] = np.arange(tree.n_nodes - 1)
    b = bone_of[lv.node]
    head = tree.parents[lv.node]
    offset = lv.pos.astype(np.float64) - tree.nodes3d[0, head].astype(np.float64)
    return tree.nodes3d[:, head].astype(np.float64) + quat_rotate(q[:, b], offset[None])


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
