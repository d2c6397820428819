"""Synthetic videos of a 3D tree swaying in wind, with exact ground truth.

Only numpy and OpenCV are used (works with numpy 1.26 and 2.x); nothing else from the project.

Coordinates and camera
----------------------
World: ``x`` right, ``y`` depth (away from the camera), ``z`` up.  World units are pixels of
frame 1.  The camera is orthographic and looks along ``+y``::

    u = cx + x          v = ground_v - z          (cx = width / 2, ground_v = ground_frac * height)

Pixel coordinates follow the OpenCV convention: the centre of pixel (column i, row j) is (i, j).
The root of the tree (node 0, trunk base) is the world origin.  An optional camera motion (shake
plus drift, ``hard`` variant) is an image-space translation ``camera_offset[f]`` (zero at frame 0),
so that what the image shows at frame f is ``nodes2d[f] + camera_offset[f]``.

Tree model
----------
The tree is a set of *branches*; each branch is a polyline of 2-5 segments starting at a *base
joint* that belongs to its parent branch (the trunk starts at the root).  Nodes are the polyline
vertices, so straight edges between parent and child nodes follow the branches.  A deciduous tree
(``kind="deciduous"``) is grown recursively: a trunk up to the first split (``trunk_frac`` of the
skeleton height), then 2-3 children per split, 25-50 deg from the parent, random azimuth, length
ratio 0.6-0.8, small random bends and a little upward tropism, ``max_order`` orders deep.  A conifer
(``kind="conifer"``) is a straight leader (a chain of order-0 branches) with whorls of 4-6
near-horizontal side branches (order 1) that get shorter to the top, each with a few short twigs
(order 2).  Radii follow the pipe model bottom-up (``r_parent^2 = sum r_child^2`` at each branch
point, slight taper along a branch), scaled so the trunk base has ``trunk_radius_frac * height`` px.

Motion
------
Every branch ``b`` rotates about its base joint by a rotation vector lying in the horizontal plane,
``w_b(t) = sum_k a_k sin(2 pi f_k t + phi_k) (cos psi_k, sin psi_k, 0)`` with 3 sinusoids
(0.3-1.5 Hz; higher orders faster and with larger angles, the trunk nearly still).  The children of
the trunk additionally get a common gust rotation (0.1-0.3 Hz sinusoid plus smooth noise), i.e.
the whole crown turns about the first split as one.  Forward kinematics (``T_b = T_parent o
Rot(w_b) about the rest base point``) gives every node's world position per frame.  ``freq`` of a
node is the frequency of the largest-amplitude sinusoid of the branch the node belongs to.  Leaves
are rigidly attached to a node's branch and add a small high-frequency 2D flutter.

Rendering
---------
Per frame: static background (sky gradient with clouds, distant hills, textured ground, a brown
fence, a brown roof and a rock so colour alone cannot find bark), then the tree in 10 depth layers
(painter's algorithm by rest ``y``, far first; per layer branches then leaves).  Branches are
anti-aliased tapered quads with round joints, three-tone cylinder shading and bark marks (cracks
and bands that move with the branch).  Leaves are small anti-aliased pointed hexagons in clusters.
Then an optional moving occluder (person-like blob), the camera translation, Gaussian sensor noise
and an optional JPEG round-trip; the video is written with ``cv2.VideoWriter`` ('mp4v').

Wind and light of real footage (``WIND_VARIANTS``; every option off by default, drawn from random
streams of their own so that a config without them renders exactly what it did before they existed)
-------------------------------------------------------------------------------------------------
Leaf cards that turn (``leaf_turn_deg``: each leaf about its petiole, its width foreshortening and its
shading changing), the thinnest branches swinging 5-15 deg (``thin_swing_deg``), strong gusts that
lean the crown by 5-10 % of the height within a second (``gust_lean``), a global light gain with a
slow and a fast part (``flicker``) and drifting cloud shadows (``cloud_shadow``), a blurred branch in
front of the crown (``foreground``, its per-frame mask in the truth), a palm (``kind="palm"``: a
curved trunk and drooping fronds of leaflets, each a chain of one-segment branches that bends), H.264
through the ffmpeg CLI (``encoder="h264"``) and frames at irregular times in an MKV whose header
declares another rate (``vfr_header_fps``). Every frame has a time (``frame_times``); the motion is
evaluated at those times. ``SEEDS`` lists each variant's development and held-out seeds.

Everything is seeded: the same config gives identical ``truth.npz`` and identical frames before
encoding (``render_frame`` is a pure function of the scene and the frame index).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

#: the variants of the first sample set; their output (truth and frames) must never change
OLD_VARIANTS = ("broad", "conifer", "sparse", "hard", "gentle", "grey", "dense")
#: variants that move like trees in real wind (issue 18): leaf cards that turn, strong gusts, thin
#: branches swinging, flickering light, a foreground branch, a conifer in a storm, a palm, a 30 s,
#: a 160x120, a 1080p H.264 and a variable-frame-rate clip
WIND_VARIANTS = ("flutter", "gusts", "flicker", "foreground", "conifer_storm", "palm", "long", "tiny", "hd",
                 "vfr")
#: variants for the look on real footage (issue 19): a dense crown front-lit under an overcast
#: sky, the same backlit (a dark silhouette against the bright sky), autumn-coloured foliage, and
#: a crown whose foliage hangs to the ground in front of its trunk (the trunk hidden)
LOOK_VARIANTS = ("frontlit", "backlit", "autumn", "hidden")
VARIANTS = OLD_VARIANTS + WIND_VARIANTS + LOOK_VARIANTS

_SHIFT = 4                     # fractional bits for OpenCV drawing (1/16 px precision)
_SUB = float(1 << _SHIFT)
_REF_HEIGHT = 360.0            # pixel sizes in the config are given for this frame height
_N_LAYERS = 10                 # depth layers of the painter's algorithm
_UP = np.array([0.0, 0.0, 1.0])

# independent random streams (combined with the seed through np.random.SeedSequence)
_S_TREE, _S_LEAVES, _S_MOTION, _S_BACKGROUND, _S_CAMERA, _S_NOISE, _S_OUTLINE, _S_BARK = range(1, 9)
# streams of the wind and light options: drawn only when an option is on, so that a config without
# them gives exactly the output it gave before they existed
_S_TURN, _S_SWING, _S_LEAN, _S_LIGHT, _S_FOREGROUND, _S_TIMES, _S_PALM, _S_SKIRT = range(9, 17)

# label values of render_labels
LABEL_BACKGROUND, LABEL_BRANCH, LABEL_LEAF, LABEL_OCCLUDER, LABEL_FOREGROUND = 0, 1, 2, 3, 4


# ----------------------------------------------------------------------------------------------
# configuration
# ----------------------------------------------------------------------------------------------
@dataclass
class SynthConfig:
    """All parameters of a synthetic tree video.  Pixel sizes marked "@360" are for a 360 px high
    frame and scale with ``height / 360``; angles in radians unless the name says deg."""

    variant: str = "broad"
    width: int = 480                 # px
    height: int = 360                # px
    frames: int = 240
    fps: float = 24.0
    seed: int = 0
    bark: str = "brown"              # "brown" | "grey"
    # --- tree shape
    kind: str = "deciduous"          # "deciduous" | "conifer" | "palm"
    max_order: int = 4               # deepest branching order (trunk = 0)
    children: tuple = (2, 3)         # min/max children per split (deciduous)
    branch_angle_deg: tuple = (25.0, 50.0)   # child angle from the parent direction
    length_ratio: tuple = (0.6, 0.8)          # child length / parent length
    trunk_frac: float = 0.35         # first split (or first whorl) height / skeleton height
    height_frac: float = 0.8         # tree height incl. leaves / frame height
    ground_frac: float = 0.9         # ground line row / frame height
    trunk_radius_frac: float = 0.02  # trunk base radius / frame height
    # --- foliage
    cluster_min_order: int = 2       # nodes of at least this order may carry a leaf cluster
    cluster_prob: float = 0.45       # chance that an inner node (not a tip) carries a cluster
    tip_cluster_prob: float = 1.0    # chance that a branch tip carries a cluster
    leaves_per_cluster: int = 26     # for a cluster of the nominal radius (scales with area)
    cluster_radius_px: float = 9.0   # @360, nominal 3D radius of a cluster
    leaf_size_px: tuple = (3.0, 8.0)  # @360, leaf length range
    front_lit: bool = False          # flat bright lighting of the crown (dense variant)
    front_clusters: bool = False     # extra clusters in front of every limb (hides them)
    fill_clusters: int = 0           # extra clusters spread through the crown volume
    skirt: bool = False              # foliage hanging from the crown to the ground around the trunk
    # --- motion
    sway_scale: float = 1.0          # multiplies all branch sway angles
    freq_scale: float = 1.0          # multiplies sway frequencies (result clipped to 0.3-1.5 Hz)
    gust_rad: float = 0.012          # crown gust rotation amplitude (rad)
    flutter_px: float = 0.5          # @360, max leaf flutter amplitude
    # --- camera / image
    noise_sigma: float = 2.5         # Gaussian sensor noise (8-bit levels)
    shake_px: float = 0.0            # @360, camera shake: std of a smooth random jitter per axis
    drift_px: float = 0.0            # @360, slow camera drift over the whole clip
    occluder: bool = False           # person-like object crossing in front of the trunk
    jpeg_quality: int = 0            # 0 = off, else JPEG round-trip quality per frame
    # --- wind and light of real footage; every option is off by default
    leaf_turn_deg: tuple = (0.0, 0.0)   # per-leaf turning amplitude range (deg; 0 = leaves only translate)
    leaf_turn_hz: tuple = (2.0, 6.0)    # per-leaf turning frequency range (Hz), each leaf its own phase
    thin_swing_deg: tuple = (0.0, 0.0)  # swing amplitude range (deg) of the thinnest branches (last order)
    thin_swing_hz: tuple = (0.8, 2.0)   # their swing frequency range (Hz)
    gust_lean: tuple = (0.0, 0.0)       # strong gusts: lean of the crown top, share of the tree height
    gust_count: int = 2                 # strong gusts in the clip (one after another, from 1 s on)
    gust_rise_s: tuple = (0.5, 1.0)     # time from calm to the full lean (s)
    flicker: float = 0.0                # global light gain range +- (0.1-0.2), a slow and a fast part
    cloud_shadow: float = 0.0           # darkening in drifting cloud shadows (0 = none, 0.3 = 30 %)
    foreground: bool = False            # a blurred branch in front of the tree swinging across the crown
    fronds: tuple = (8, 14)             # palm: frond count range
    sky: str = "blue"                   # "blue" | "overcast" (a bright, nearly white sky)
    light: str = "sun"                  # "sun" | "backlit" (crown and bark a dark silhouette)
    palette: str = "green"              # foliage colours: "green" | "autumn" (reds and oranges)
    encoder: str = "mp4v"               # "mp4v" (cv2.VideoWriter, video.mp4) | "h264" (ffmpeg CLI, libx264)
    vfr_header_fps: float = 0.0         # > 0: frames at irregular times (mean rate fps), H.264 in video.mkv
    #                                     whose header declares this rate


_PRESETS: dict[str, dict] = {
    "broad": {},
    "conifer": dict(kind="conifer", max_order=2, trunk_frac=0.22, height_frac=0.82,
                    trunk_radius_frac=0.016, cluster_min_order=1, cluster_prob=1.0,
                    leaves_per_cluster=26, cluster_radius_px=7.0, leaf_size_px=(3.0, 6.0),
                    sway_scale=2.5, seed=0),
    "sparse": dict(max_order=3, cluster_min_order=2, cluster_prob=0.05, tip_cluster_prob=0.6,
                   leaves_per_cluster=9, cluster_radius_px=6.0, trunk_radius_frac=0.015,
                   trunk_frac=0.3, seed=2),
    "hard": dict(gust_rad=0.045, sway_scale=1.3, noise_sigma=6.0, shake_px=0.8, drift_px=4.0,
                 occluder=True, jpeg_quality=80, seed=3),
    "gentle": dict(sway_scale=0.11, freq_scale=0.7, gust_rad=0.0, flutter_px=0.04, seed=0),
    "grey": dict(bark="grey", seed=5),
    "dense": dict(children=(3, 3), cluster_min_order=1, cluster_prob=1.0, leaves_per_cluster=30,
                  cluster_radius_px=14.0, front_lit=True, front_clusters=True, fill_clusters=40,
                  trunk_frac=0.3,
                  seed=6),
}
_CONIFER = {k: v for k, v in _PRESETS["conifer"].items() if k != "seed"}
_WIND = dict(leaf_turn_deg=(5.0, 15.0), thin_swing_deg=(5.0, 15.0))
_GUSTS = dict(gust_lean=(0.05, 0.10), gust_count=2, gust_rise_s=(0.5, 1.0))
_PRESETS.update({
    "flutter": dict(_WIND),                                                  # steady breeze, leaves turning
    "gusts": dict(_WIND, **_GUSTS),                                          # two gusts that lean the crown
    "flicker": dict(_WIND, flicker=0.15, cloud_shadow=0.3),                  # light gain +-15 %, clouds
    "foreground": dict(_WIND, foreground=True),                              # a blurred branch in front
    "conifer_storm": dict(_CONIFER, **_WIND, **_GUSTS, sway_scale=5.0, gust_rad=0.03),
    "palm": dict(kind="palm", bark="grey", height_frac=0.84, trunk_radius_frac=0.016, leaf_size_px=(10.0, 24.0),
                 cluster_radius_px=2.0, leaf_turn_deg=(5.0, 15.0), gust_lean=(0.05, 0.10), gust_count=2,
                 sway_scale=1.0),
    "long": dict(_WIND, frames=720, gust_lean=(0.05, 0.08), gust_count=4),  # 30 s
    "tiny": dict(_CONIFER, **_WIND, **_GUSTS, width=160, height=120, fps=15.0, frames=150, sway_scale=7.0,
                 freq_scale=1.5, height_frac=0.78),          # a webcam-like clip of a young conifer, gusty
    "hd": dict(_WIND, width=1920, height=1080, frames=48, encoder="h264", sway_scale=1.5),
    "vfr": dict(_WIND, fps=12.0, frames=96, vfr_header_fps=30.0, encoder="h264"),
})
_DENSE = {k: v for k, v in _PRESETS["dense"].items() if k != "seed"}
_PRESETS.update({
    "frontlit": dict(_DENSE, sky="overcast", frames=48),
    "backlit": dict(_DENSE, sky="overcast", light="backlit", frames=48),
    "autumn": dict(_DENSE, palette="autumn", frames=48),
    "hidden": dict(_DENSE, skirt=True, frames=48),
})

#: seeds per variant: "dev" ones may be looked at while developing the reconstruction, "held_out"
#: ones never (sample_videos/README.md); the preset's own seed is the first dev seed
SEEDS: dict[str, dict[str, tuple]] = {
    v: {"dev": (int(_PRESETS[v].get("seed", 0)),), "held_out": (101, 102)} for v in OLD_VARIANTS}
SEEDS.update({v: {"dev": (0, 1), "held_out": (2, 3)} for v in WIND_VARIANTS + LOOK_VARIANTS})


def config_for(variant: str, **overrides) -> SynthConfig:
    """Preset config of ``variant`` (one of VARIANTS); keyword ``overrides`` (any SynthConfig field)
    are applied last, overrides whose value is None are ignored."""
    if variant not in _PRESETS:
        raise ValueError(f"unknown variant {variant!r}; expected one of {VARIANTS}")
    names = {f.name for f in fields(SynthConfig)}
    bad = set(overrides) - names
    if bad:
        raise TypeError(f"unknown SynthConfig fields: {sorted(bad)}")
    values = dict(_PRESETS[variant])
    values.update({k: v for k, v in overrides.items() if v is not None})
    values["variant"] = variant
    return SynthConfig(**values)


def _scale(cfg: SynthConfig) -> float:
    """Pixel scale of the frame relative to the 360 px reference height."""
    return cfg.height / _REF_HEIGHT


def _rng(cfg: SynthConfig, stream: int, *extra: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(cfg.seed), stream, *extra]))


def _unit(v: np.ndarray) -> np.ndarray:
    """Normalise vectors along the last axis."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-12)


# ----------------------------------------------------------------------------------------------
# tree skeleton
# ----------------------------------------------------------------------------------------------
@dataclass
class Tree:
    """Rest geometry of the tree skeleton (N nodes, B branches), world px.

    rest (N, 3) float64 rest positions; parents (N,) int32 (-1 for the root); node_branch (N,)
    int32 branch whose motion moves the node (root: trunk 0); radius (N,) float64 px;
    depth_level (N,) int32 branching order; branch_parent (B,) int32 (-1 for the trunk);
    branch_base (B,) int32 joint node each branch rotates about; branch_depth (B,) int32;
    branch_base_radius (B,) float64 px radius where the branch leaves its joint;
    branch_nodes: list of B int arrays, the branch's own nodes from base to tip (joint excluded).
    Palms only: part (N,) int8 0 = trunk, 1 = frond; frond (N,) int32 frond index (-1 on the
    trunk); trunk_branches (T,) int the trunk's chain of one-segment branches, root first;
    frond_branches: list of int arrays, each frond's chain of one-segment branches, base first.
    """

    rest: np.ndarray
    parents: np.ndarray
    node_branch: np.ndarray
    radius: np.ndarray
    depth_level: np.ndarray
    branch_parent: np.ndarray
    branch_base: np.ndarray
    branch_depth: np.ndarray
    branch_base_radius: np.ndarray
    branch_nodes: list
    part: np.ndarray | None = None
    frond: np.ndarray | None = None
    trunk_branches: np.ndarray | None = None
    frond_branches: list | None = None


class _TreeBuilder:
    """Accumulates nodes and branches (nominal units) while a tree is grown."""

    def __init__(self, rng: np.random.Generator):
        self.rng = rng
        self.pos = [np.zeros(3)]
        self.parent = [-1]
        self.node_branch = [0]
        self.depth = [0]
        self.b_parent: list[int] = []
        self.b_base: list[int] = []
        self.b_depth: list[int] = []
        self.b_nodes: list[list[int]] = []

    def add_branch(self, parent_branch: int, base_node: int, direction, length: float,
                   depth: int, nseg: int, bend: float, tropism: float) -> int:
        """Append a branch polyline of ``nseg`` segments from ``base_node``; returns its index.
        ``bend`` is the std of the random direction change per segment, ``tropism`` pulls the
        direction up (>0) or down (<0) per segment."""
        b = len(self.b_parent)
        cur = self.pos[base_node].copy()
        d = _unit(np.asarray(direction, float))
        prev, nodes = base_node, []
        for k in range(nseg):
            if k > 0:
                d = _unit(d + bend * self.rng.standard_normal(3) + tropism * _UP)
            cur = cur + d * (length / nseg)
            idx = len(self.pos)
            self.pos.append(cur)
            self.parent.append(prev)
            self.node_branch.append(b)
            self.depth.append(depth)
            nodes.append(idx)
            prev = idx
        self.b_parent.append(parent_branch)
        self.b_base.append(base_node)
        self.b_depth.append(depth)
        self.b_nodes.append(nodes)
        return b

    def end_direction(self, b: int) -> np.ndarray:
        nodes = self.b_nodes[b]
        prev = self.b_base[b] if len(nodes) < 2 else nodes[-2]
        return _unit(self.pos[nodes[-1]] - self.pos[prev])


def _child_direction(parent_dir: np.ndarray, polar: float, azimuth: float) -> np.ndarray:
    """Unit vector at angle ``polar`` (rad) from ``parent_dir`` with azimuth ``azimuth`` (rad)
    around it (azimuth 0 = towards +x projected)."""
    d = _unit(parent_dir)
    helper = np.array([0.0, 1.0, 0.0]) if abs(d[0]) > 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = _unit(helper - d * np.dot(helper, d))
    e2 = np.cross(d, e1)
    return _unit(math.cos(polar) * d + math.sin(polar) * (math.cos(azimuth) * e1
                                                          + math.sin(azimuth) * e2))


def _grow_deciduous(cfg: SynthConfig, rng: np.random.Generator) -> _TreeBuilder:
    """Recursive broad-leaved tree in nominal units (trunk length 1)."""
    tb = _TreeBuilder(rng)
    trunk_dir = _unit(np.array([rng.normal(0, 0.03), rng.normal(0, 0.03), 1.0]))
    trunk = tb.add_branch(-1, 0, trunk_dir, 1.0, 0, int(rng.integers(4, 6)), 0.03, 0.0)
    lo, hi = np.radians(cfg.branch_angle_deg)

    def grow(b: int, length: float, depth: int) -> None:
        tip = tb.b_nodes[b][-1]
        d_end = tb.end_direction(b)
        k = int(rng.integers(cfg.children[0], cfg.children[1] + 1))
        az0 = rng.uniform(0, 2 * np.pi)
        for i in range(k):
            if depth >= 2 and i > 0 and rng.random() < 0.12:
                continue                                     # a little irregularity
            polar = rng.uniform(lo, hi)
            az = az0 + 2 * np.pi * i / k + rng.uniform(-0.35, 0.35)
            clen = length * rng.uniform(*cfg.length_ratio)
            nseg = int(rng.integers(3, 6)) if depth == 0 else int(rng.integers(2, 5))
            c = tb.add_branch(b, tip, _child_direction(d_end, polar, az), clen, depth + 1,
                              nseg, 0.12, 0.08)
            if depth + 1 < cfg.max_order:
                grow(c, clen, depth + 1)

    grow(trunk, 1.0, 0)
    _stretch_trunk(tb, cfg.trunk_frac)
    return tb


def _stretch_trunk(tb: _TreeBuilder, trunk_frac: float) -> None:
    """Rescale the trunk so that the first split sits at ``trunk_frac`` of the skeleton height."""
    pos = np.array(tb.pos)
    trunk_nodes = np.array([0] + tb.b_nodes[0])
    top_old = pos[tb.b_nodes[0][-1]].copy()
    crown = pos[:, 2].max() - top_old[2]
    want = trunk_frac / (1.0 - trunk_frac) * crown
    k = want / top_old[2]
    in_trunk = np.zeros(len(pos), bool)
    in_trunk[trunk_nodes] = True
    pos[in_trunk] *= k
    pos[~in_trunk] += pos[tb.b_nodes[0][-1]] - top_old
    tb.pos = list(pos)


def _grow_conifer(cfg: SynthConfig, rng: np.random.Generator) -> _TreeBuilder:
    """Conifer in nominal units (skeleton height 1): straight leader, whorls of side branches."""
    tb = _TreeBuilder(rng)
    z1 = cfg.trunk_frac
    n_whorls = int(rng.integers(11, 14))
    whorl_z = np.linspace(z1, 0.91, n_whorls)
    whorl_z[1:] += rng.uniform(-0.012, 0.012, n_whorls - 1)
    lean = np.array([rng.normal(0, 0.01), rng.normal(0, 0.01), 1.0])
    seg = tb.add_branch(-1, 0, lean, z1, 0, 3, 0.005, 0.0)
    for wi, z in enumerate(whorl_z):
        base = tb.b_nodes[seg][-1]
        h = (z - z1) / (1.0 - z1)                       # 0 at the first whorl, ~1 at the top
        side_len = 0.21 * (1.0 - h) ** 0.95 + 0.03
        n_side = int(rng.integers(4, 7))
        az0 = rng.uniform(0, 2 * np.pi)
        for i in range(n_side):
            az = az0 + 2 * np.pi * i / n_side + rng.uniform(-0.3, 0.3)
            polar = np.radians(96.0 - 34.0 * h + rng.uniform(-6, 6))
            length = side_len * rng.uniform(0.85, 1.15)
            sb = tb.add_branch(seg, base, _child_direction(_UP, polar, az), length, 1,
                               3 if length > 0.07 else 2, 0.05, -0.04)
            _add_conifer_twigs(tb, rng, sb, length)
        top_z = whorl_z[wi + 1] if wi + 1 < n_whorls else 1.0
        step = top_z - tb.pos[base][2]
        seg = tb.add_branch(seg, base, lean, step, 0, 2, 0.005, 0.0)
    return tb


def _add_conifer_twigs(tb: _TreeBuilder, rng: np.random.Generator, sb: int, length: float) -> None:
    """Short order-2 twigs left and right of the side branch ``sb`` at its inner nodes."""
    for node in tb.b_nodes[sb][:-1]:
        parent_node = tb.parent[node]
        d = _unit(tb.pos[node] - tb.pos[parent_node])
        perp = _unit(np.cross(d, _UP))
        for side in (-1.0, 1.0):
            if rng.random() < 0.75:
                a = np.radians(rng.uniform(35, 60))
                td = _unit(math.cos(a) * d + side * math.sin(a) * perp - 0.15 * _UP)
                tb.add_branch(sb, node, td, length * rng.uniform(0.3, 0.45), 2, 2, 0.05, -0.02)


def _grow_palm(cfg: SynthConfig, rng: np.random.Generator) -> tuple[_TreeBuilder, list, list]:
    """Palm in nominal units (trunk length 1): a trunk of 7-9 one-segment branches that leans and
    curves (a C or an S), and ``cfg.fronds`` fronds from its top, each a chain of 7 one-segment
    branches that arches out and droops. Returns the builder, the trunk's branches and the
    fronds' branch chains."""
    tb = _TreeBuilder(rng)
    n_t = int(rng.integers(7, 10))
    side = 1.0 if rng.random() < 0.5 else -1.0
    lean_dir = _unit(np.array([side, rng.uniform(-0.5, 0.5), 0.0]))
    lean0 = rng.uniform(0.06, 0.3)                    # rad from vertical at the base
    curve = rng.uniform(-0.2, 1.4)                    # > 1: bends back past vertical (an S)
    seg_len = 1.0 / n_t
    trunk, node, parent_b = [], 0, -1
    for k in range(n_t):
        ang = lean0 * (1.0 - curve * k / (n_t - 1)) + rng.normal(0, 0.015)
        d = _unit(math.sin(ang) * lean_dir + math.cos(ang) * _UP)
        parent_b = tb.add_branch(parent_b, node, d, seg_len, 0, 1, 0.0, 0.0)
        node = tb.b_nodes[parent_b][-1]
        trunk.append(parent_b)
    top = node
    n_f = int(rng.integers(cfg.fronds[0], cfg.fronds[1] + 1))
    golden = np.pi * (3.0 - math.sqrt(5.0))
    az0 = rng.uniform(0, 2 * np.pi)
    order = rng.permutation(n_f)
    fronds = []
    for i in range(n_f):
        az = az0 + golden * i + rng.uniform(-0.2, 0.2)
        rank = order[i] / max(n_f - 1, 1)             # 0: the youngest, most upright frond
        polar = np.radians(15.0 + 70.0 * rank + rng.uniform(-5, 5))
        length = rng.uniform(0.42, 0.62) * (0.8 + 0.2 * rank)
        n_s = 7
        droop = rng.uniform(0.12, 0.24)
        chain, b, base = [], trunk[-1], top
        for k in range(n_s):
            pol = min(polar + droop * k * (1.0 + k / n_s), np.radians(165.0))
            d = _child_direction(_UP, pol, az)
            b = tb.add_branch(b, base, d, length / n_s, 1, 1, 0.0, 0.0)
            base = tb.b_nodes[b][-1]
            chain.append(b)
        fronds.append(chain)
    return tb, trunk, fronds


def _palm_radii(cfg: SynthConfig, tb: _TreeBuilder, trunk: list, fronds: list,
                scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Radii (px) of a palm: per node (N,) and per branch base (B,). The trunk hardly tapers
    (``trunk_radius_frac`` x height at the base, a flare below, 80 % at the top), a frond's rachis
    goes from 1.5 to 0.5 px @360."""
    s = _scale(cfg)
    n = len(tb.pos)
    radius = np.zeros(n)
    base_r = np.zeros(len(tb.b_parent))
    r_trunk = cfg.trunk_radius_frac * cfg.height
    z = np.array(tb.pos)[:, 2] * scale
    z_top = z[tb.b_nodes[trunk[-1]][-1]]
    for b in trunk:
        nd = tb.b_nodes[b][-1]
        radius[nd] = r_trunk * (1.0 - 0.2 * z[nd] / max(z_top, 1e-9))
    radius[0] = r_trunk * 1.35
    for b in trunk:
        base_r[b] = radius[tb.b_base[b]] if tb.b_base[b] != 0 else r_trunk * 1.1
    for chain in fronds:
        for k, b in enumerate(chain):
            nd = tb.b_nodes[b][-1]
            radius[nd] = max(1.5 * s * (1.0 - (k + 1) / len(chain)) + 0.5 * s, 0.4)
            base_r[b] = 1.5 * s if k == 0 else radius[tb.b_base[b]]
    return radius, base_r


def _pipe_radii(tb: _TreeBuilder, taper: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Pipe-model radii (nominal tip radius 1): per node (N,) and per branch base (B,)."""
    n_nodes, n_br = len(tb.pos), len(tb.b_parent)
    r2 = np.zeros(n_nodes)
    base_r2 = np.zeros(n_br)
    attached: dict[int, list[int]] = {}
    for b in range(1, n_br):
        attached.setdefault(tb.b_base[b], []).append(b)
    for b in range(n_br - 1, -1, -1):                  # children were created after parents
        nodes = tb.b_nodes[b]
        grow = 1.0 + taper / len(nodes)
        acc = 0.0 if nodes[-1] in attached else 1.0
        for n in reversed(nodes):
            acc += sum(base_r2[c] for c in attached.get(n, []))
            r2[n] = acc
            acc *= grow
        base_r2[b] = acc
    r2[0] = base_r2[0] * 1.44                            # root flare (1.2 x radius)
    return np.sqrt(r2), np.sqrt(base_r2)


def build_tree(cfg: SynthConfig) -> Tree:
    """Grow the tree of ``cfg`` and scale it to frame pixels (see module docstring)."""
    rng = _rng(cfg, _S_TREE)
    if cfg.kind == "palm":
        return _build_palm(cfg, rng)
    tb = _grow_conifer(cfg, rng) if cfg.kind == "conifer" else _grow_deciduous(cfg, rng)
    pos = np.array(tb.pos)
    s = _scale(cfg)
    leaf_margin = 1.1 * cfg.cluster_radius_px * s + 0.5 * cfg.leaf_size_px[1] * s
    scale = (cfg.height_frac * cfg.height - leaf_margin) / pos[:, 2].max()
    pos *= scale
    radius, base_r = _pipe_radii(tb)
    rscale = cfg.trunk_radius_frac * cfg.height / base_r[0]
    radius = np.maximum(radius * rscale, 0.4)
    base_r = np.maximum(base_r * rscale, 0.4)
    return Tree(rest=pos, parents=np.array(tb.parent, np.int32),
                node_branch=np.array(tb.node_branch, np.int32), radius=radius,
                depth_level=np.array(tb.depth, np.int32),
                branch_parent=np.array(tb.b_parent, np.int32),
                branch_base=np.array(tb.b_base, np.int32),
                branch_depth=np.array(tb.b_depth, np.int32),
                branch_base_radius=base_r,
                branch_nodes=[np.array(n, np.int64) for n in tb.b_nodes])


def _build_palm(cfg: SynthConfig, rng: np.random.Generator) -> Tree:
    """The palm of ``cfg`` in frame pixels, its crown kept inside the frame's width."""
    tb, trunk, fronds = _grow_palm(cfg, rng)
    pos = np.array(tb.pos)
    s = _scale(cfg)
    leaf_margin = 1.1 * cfg.cluster_radius_px * s + 0.5 * cfg.leaf_size_px[1] * s
    scale = (cfg.height_frac * cfg.height - leaf_margin) / pos[:, 2].max()
    half_w = 0.5 * cfg.width - 1.2 * cfg.leaf_size_px[1] * s - 4.0 * s
    scale = min(scale, half_w / max(np.abs(pos[:, 0]).max(), 1e-9))
    pos *= scale
    radius, base_r = _palm_radii(cfg, tb, trunk, fronds, scale)
    n = len(pos)
    part = np.zeros(n, np.int8)
    frond = -np.ones(n, np.int32)
    for j, chain in enumerate(fronds):
        for b in chain:
            part[tb.b_nodes[b]] = 1
            frond[tb.b_nodes[b]] = j
    return Tree(rest=pos, parents=np.array(tb.parent, np.int32),
                node_branch=np.array(tb.node_branch, np.int32), radius=np.maximum(radius, 0.4),
                depth_level=np.array(tb.depth, np.int32),
                branch_parent=np.array(tb.b_parent, np.int32),
                branch_base=np.array(tb.b_base, np.int32),
                branch_depth=np.array(tb.b_depth, np.int32),
                branch_base_radius=np.maximum(base_r, 0.4),
                branch_nodes=[np.array(nd, np.int64) for nd in tb.b_nodes],
                part=part, frond=frond, trunk_branches=np.array(trunk, np.int64),
                frond_branches=[np.array(c, np.int64) for c in fronds])


# ----------------------------------------------------------------------------------------------
# foliage
# ----------------------------------------------------------------------------------------------
@dataclass
class Leaves:
    """Lv leaves in C clusters.  node/branch (Lv,) int attachment; rest (Lv, 3) world px;
    shape (Lv, 6, 2) float image-plane polygon offsets px; color list of Lv BGR tuples;
    flutter_amp/freq/phase (Lv, 2) px / Hz / rad; cluster (Lv,) int; cluster_dark (C,) bool.
    Turning cards (``leaf_turn_deg``): turn_amp (Lv,) rad, turn_freq (Lv,) Hz, turn_phase (Lv,)
    rad, tilt (Lv,) rad rest tilt of the card against the image plane. Palm leaflets: axis (Lv, 3)
    world direction of the leaflet, so that its polygon turns with its frond segment."""

    node: np.ndarray
    branch: np.ndarray
    rest: np.ndarray
    shape: np.ndarray
    color: list
    flutter_amp: np.ndarray
    flutter_freq: np.ndarray
    flutter_phase: np.ndarray
    cluster: np.ndarray
    cluster_dark: np.ndarray
    turn_amp: np.ndarray | None = None
    turn_freq: np.ndarray | None = None
    turn_phase: np.ndarray | None = None
    tilt: np.ndarray | None = None
    axis: np.ndarray | None = None


_PALETTE_DECIDUOUS = ((22, 58, 30), (42, 122, 66), (74, 172, 112), (105, 212, 178))
_PALETTE_AUTUMN = ((24, 40, 96), (28, 70, 172), (40, 112, 222), (96, 176, 248))   # BGR reds, oranges
#: a backlit crown and its bark: the light reaching the camera through or around them
BACKLIT_GAIN = 0.12
_PALETTE_CONIFER = ((28, 56, 24), (50, 94, 44), (72, 126, 66), (96, 152, 104))
_SUN = _unit(np.array([-0.5, -0.55, 0.7]))          # from upper left, in front of the tree


def _cluster_sites(cfg: SynthConfig, tree: Tree, rng: np.random.Generator, s: float):
    """Cluster centres (C, 3), radii (C,) px and attachment nodes (C,)."""
    n = len(tree.rest)
    has_child = np.zeros(n, bool)
    has_child[tree.parents[tree.parents >= 0]] = True
    order_ok = (tree.depth_level >= cfg.cluster_min_order) & (np.arange(n) > 0)
    u = rng.random(n)
    pick = order_ok & np.where(has_child, u < cfg.cluster_prob, u < cfg.tip_cluster_prob)
    nodes = list(np.nonzero(pick)[0])
    offsets = []
    r0 = cfg.cluster_radius_px * s
    radii = list(r0 * rng.uniform(0.75, 1.25, len(nodes)))
    for nd in nodes:
        p = tree.rest[nd]
        out = _unit(np.array([p[0], p[1], 0.0]))
        offsets.append(0.3 * out + 0.2 * _UP)
    top = tree.rest[:, 2].max()
    front = []
    if cfg.kind == "conifer":                          # hide the leader in the upper half
        front = [nd for nd in range(1, n) if tree.depth_level[nd] == 0
                 and tree.rest[nd, 2] > 0.45 * top]
    elif cfg.front_clusters:                           # hide every limb
        split_z = tree.rest[tree.branch_nodes[0][-1], 2]
        front = [nd for nd in range(1, n) if 1 <= tree.depth_level[nd] <= 2
                 or (tree.depth_level[nd] == 0 and tree.rest[nd, 2] > 0.7 * split_z)]
    for nd in front:
        nodes.append(nd)
        radii.append(r0 * rng.uniform(1.0, 1.3))
        offsets.append(np.array([0.0, -0.7, 0.1]))
    nodes = np.array(nodes, np.int64)
    radii = np.array(radii)
    offsets = np.array(offsets).reshape(-1, 3)
    centres = tree.rest[nodes] + radii[:, None] * (offsets + 0.2 * rng.standard_normal((len(nodes), 3)))
    if cfg.fill_clusters > 0:
        fc, fr, fn = _fill_sites(tree, rng, cfg.fill_clusters, r0)
        centres, radii, nodes = (np.concatenate([centres, fc]), np.concatenate([radii, fr]),
                                 np.concatenate([nodes, fn]))
    if cfg.skirt:
        sc, sr, sn = _skirt_sites(cfg, tree, r0)
        centres, radii, nodes = (np.concatenate([centres, sc]), np.concatenate([radii, sr]),
                                 np.concatenate([nodes, sn]))
    return centres, radii, nodes


def _skirt_sites(cfg: SynthConfig, tree: Tree, r0: float):
    """Clusters hanging from the crown to the ground (``skirt``): a column in front of the trunk
    from the first fork down to one cluster radius above the ground, and a curtain 0.75 of the
    crown's width under the fork narrowing to 0.5 at the ground (most of it in front), each
    attached to its nearest limb node so it sways with the crown; the trunk is hidden from the
    fork to the ground."""
    rng = _rng(cfg, _S_SKIRT)
    split_z = float(tree.rest[tree.branch_nodes[0][-1], 2])
    crown = np.nonzero(tree.depth_level >= 1)[0]
    pts = tree.rest[crown]
    cx, half = 0.5 * (pts[:, 0].min() + pts[:, 0].max()), 0.5 * np.ptp(pts[:, 0])
    zs = np.arange(0.8 * r0, split_z + r0, 0.8 * r0)
    col = np.stack([rng.normal(0, 0.3 * r0, len(zs)), rng.uniform(-1.2, -0.6, len(zs)) * r0, zs], 1)
    # the curtain: 0.75 of the crown's width under the fork, narrowing to 0.5 at the ground
    n = int(max(8, round(1.25 * half * split_z / (1.2 * r0) ** 2)))
    z = rng.uniform(0.8 * r0, split_z + r0, n)
    w = half * (0.5 + 0.25 * np.clip(z / split_z, 0, 1))
    cur = np.stack([cx + w * rng.uniform(-1, 1, n), rng.uniform(-1.5, 1.0, n) * r0, z], 1)
    centres = np.concatenate([col, cur])
    near = np.argmin(((centres[:, None, :] - pts[None]) ** 2).sum(-1), axis=1)
    return centres, r0 * rng.uniform(1.0, 1.3, len(centres)), crown[near]


def _fill_sites(tree: Tree, rng: np.random.Generator, count: int, r0: float):
    """``count`` cluster centres uniformly inside the crown's bounding ellipsoid (order >= 1
    nodes), each attached to its nearest crown node."""
    crown = np.nonzero(tree.depth_level >= 1)[0]
    pts = tree.rest[crown]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c, half = 0.5 * (lo + hi), 0.5 * (hi - lo) * np.array([0.9, 0.9, 0.85])
    d = _unit(rng.standard_normal((count, 3))) * rng.random((count, 1)) ** (1 / 3)
    centres = c + d * half
    near = np.argmin(((centres[:, None, :] - pts[None]) ** 2).sum(-1), axis=1)
    return centres, r0 * rng.uniform(1.0, 1.4, count), crown[near]


def build_leaves(cfg: SynthConfig, tree: Tree) -> Leaves:
    """Leaf clusters around the outer branches with lighting-dependent greens (palms: leaflets
    along the fronds); with ``leaf_turn_deg`` every leaf card turns."""
    leaves = _palm_leaves(cfg, tree) if cfg.kind == "palm" else _cluster_leaves(cfg, tree)
    if cfg.leaf_turn_deg[1] > 0:
        rng = _rng(cfg, _S_TURN)
        lv = len(leaves.cluster)
        leaves.turn_amp = np.radians(rng.uniform(*cfg.leaf_turn_deg, lv))
        leaves.turn_freq = rng.uniform(*cfg.leaf_turn_hz, lv)
        leaves.turn_phase = rng.uniform(0, 2 * np.pi, lv)
        leaves.tilt = np.radians(rng.uniform(-50.0, 50.0, lv))
    return leaves


def _cluster_leaves(cfg: SynthConfig, tree: Tree) -> Leaves:
    """Leaf clusters around the outer branches (deciduous and conifer)."""
    rng = _rng(cfg, _S_LEAVES)
    s = _scale(cfg)
    centres, radii, nodes = _cluster_sites(cfg, tree, rng, s)
    conifer = cfg.kind == "conifer"
    palette = np.array(_PALETTE_CONIFER if conifer else
                       _PALETTE_AUTUMN if cfg.palette == "autumn" else _PALETTE_DECIDUOUS, float)
    crown_c = centres.mean(axis=0) if len(centres) else np.zeros(3)
    r_nom = cfg.cluster_radius_px * s
    counts = np.maximum(3, np.round(cfg.leaves_per_cluster * (radii / r_nom) ** 2
                                    * rng.uniform(0.8, 1.2, len(radii)))).astype(int)
    cl = np.repeat(np.arange(len(radii)), counts)
    lv = len(cl)
    dirs = _unit(rng.standard_normal((lv, 3)))
    rad = radii[cl] * rng.random(lv) ** (1 / 3)
    rest = centres[cl] + dirs * rad[:, None]
    # lighting
    light_c = _unit(centres - crown_c) @ _SUN
    if cfg.front_lit:
        tone_c = 0.72 + 0.08 * light_c + rng.normal(0, 0.05, len(radii))
    else:
        tone_c = 0.5 + 0.32 * light_c + rng.normal(0, 0.12, len(radii))
    if conifer:
        tone_c = tone_c * 0.8
    tone = tone_c[cl] + rng.normal(0, 0.1, lv) + 0.15 * (dirs @ _SUN)
    tone = np.clip(tone, 0.0, 1.0)
    col = np.where(tone[:, None] < 0.5,
                   palette[0] + (palette[1] - palette[0]) * (2 * tone[:, None]),
                   palette[1] + (palette[2] - palette[1]) * (2 * tone[:, None] - 1))
    sunlit = rng.random(lv) < 0.14 * tone ** 2
    col[sunlit] = palette[3]
    col = np.clip(col + rng.normal(0, 4, (lv, 3)), 0, 255)
    if cfg.light == "backlit":
        col = col * BACKLIT_GAIN
    lum = col @ np.array([0.114, 0.587, 0.299])
    c_lum = np.bincount(cl, lum, len(radii)) / np.maximum(np.bincount(cl, None, len(radii)), 1)
    shape = _leaf_shapes(rng, lv, np.array(cfg.leaf_size_px) * s, needle=conifer)
    fl_amp = cfg.flutter_px * s * rng.uniform(0.3, 1.0, (lv, 2))
    return Leaves(node=nodes[cl], branch=tree.node_branch[nodes[cl]], rest=rest, shape=shape,
                  color=[tuple(float(v) for v in c) for c in col], flutter_amp=fl_amp,
                  flutter_freq=rng.uniform(2.0, 4.5, (lv, 2)),
                  flutter_phase=rng.uniform(0, 2 * np.pi, (lv, 2)), cluster=cl,
                  cluster_dark=c_lum < np.median(c_lum))


_PALETTE_PALM = ((30, 78, 58), (44, 128, 98), (70, 168, 136), (112, 204, 178))


def _palm_leaves(cfg: SynthConfig, tree: Tree) -> Leaves:
    """Leaflets in pairs along every frond, every 2.4 px @360: longest mid-frond, hanging down
    and out from the rachis. One cluster per frond segment."""
    rng = _rng(cfg, _S_PALM)
    s = _scale(cfg)
    lmax = cfg.leaf_size_px[1] * s
    cen, axis, node, cl, lens = [], [], [], [], []
    for chain in tree.frond_branches:
        base = tree.branch_base[chain[0]]
        pts = np.concatenate([tree.rest[[base]], tree.rest[[tree.branch_nodes[b][-1] for b in chain]]])
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        total = arc[-1]
        for a in np.arange(0.08 * total, 0.98 * total, 2.4 * s):
            k = min(int(np.searchsorted(arc, a, side="right")) - 1, len(chain) - 1)
            u = (a - arc[k]) / max(seg[k], 1e-9)
            p = pts[k] + (pts[k + 1] - pts[k]) * u
            tan = _unit(pts[k + 1] - pts[k])
            side = np.cross(tan, _UP)
            side = _unit(side) if np.linalg.norm(side) > 1e-3 else np.array([1.0, 0.0, 0.0])
            frac = a / total
            length = lmax * (0.35 + 0.65 * math.sin(math.pi * frac) ** 0.7) * rng.uniform(0.85, 1.1)
            for sgn in (-1.0, 1.0):
                beta = np.radians(rng.uniform(50.0, 70.0))
                d = _unit(math.cos(beta) * tan + sgn * math.sin(beta) * side - rng.uniform(0.3, 0.8) * _UP)
                cen.append(p + d * 0.5 * length)
                axis.append(d)
                node.append(tree.branch_nodes[chain[k]][-1])
                cl.append(chain[k])
                lens.append(length)
    cen, axis = np.array(cen), np.array(axis)
    node = np.array(node, np.int64)
    _, cl = np.unique(np.array(cl), return_inverse=True)
    lv = len(cen)
    lengths = np.maximum(np.array(lens), 1.0)
    proj = np.stack([axis[:, 0], -axis[:, 2]], 1)
    plen = np.linalg.norm(proj, axis=1)
    th = np.arctan2(proj[:, 1], proj[:, 0])
    a = 0.5 * lengths * np.maximum(plen, 0.15)
    b = np.maximum(0.5 * rng.uniform(1.2, 1.8, lv) * s, 0.35)
    unit_x = np.array([1.0, 0.4, -0.4, -1.0, -0.4, 0.4])
    unit_y = np.array([0.0, 1.0, 1.0, 0.0, -1.0, -1.0])
    loc = np.stack([a[:, None] * unit_x, b[:, None] * unit_y], axis=-1)
    c, si = np.cos(th)[:, None], np.sin(th)[:, None]
    shape = np.stack([c * loc[..., 0] - si * loc[..., 1], si * loc[..., 0] + c * loc[..., 1]], -1)
    palette = np.array(_PALETTE_PALM, float)
    tone = np.clip(0.5 + 0.3 * (axis @ _SUN) + rng.normal(0, 0.12, lv), 0.0, 1.0)
    col = np.where(tone[:, None] < 0.5,
                   palette[0] + (palette[1] - palette[0]) * (2 * tone[:, None]),
                   palette[1] + (palette[2] - palette[1]) * (2 * tone[:, None] - 1))
    col[rng.random(lv) < 0.1 * tone ** 2] = palette[3]
    col = np.clip(col + rng.normal(0, 4, (lv, 3)), 0, 255)
    lum = col @ np.array([0.114, 0.587, 0.299])
    ncl = int(cl.max()) + 1 if lv else 0
    c_lum = np.bincount(cl, lum, ncl) / np.maximum(np.bincount(cl, None, ncl), 1)
    return Leaves(node=node, branch=tree.node_branch[node], rest=cen, shape=shape,
                  color=[tuple(float(v) for v in c) for c in col],
                  flutter_amp=cfg.flutter_px * s * rng.uniform(0.3, 1.0, (lv, 2)),
                  flutter_freq=rng.uniform(2.0, 4.5, (lv, 2)),
                  flutter_phase=rng.uniform(0, 2 * np.pi, (lv, 2)), cluster=cl,
                  cluster_dark=c_lum < np.median(c_lum), axis=axis)


def _leaf_shapes(rng: np.random.Generator, n: int, size_range: np.ndarray, needle: bool) -> np.ndarray:
    """(n, 6, 2) pointed-ellipse leaf polygons (px offsets) with random size and orientation."""
    a = 0.5 * rng.uniform(size_range[0], size_range[1], n)
    b = a * (rng.uniform(0.15, 0.28, n) if needle else rng.uniform(0.35, 0.6, n))
    unit_x = np.array([1.0, 0.4, -0.4, -1.0, -0.4, 0.4])
    unit_y = np.array([0.0, 1.0, 1.0, 0.0, -1.0, -1.0])
    loc = np.stack([a[:, None] * unit_x, b[:, None] * unit_y], axis=-1)
    th = rng.uniform(0, np.pi, n)
    c, si = np.cos(th)[:, None], np.sin(th)[:, None]
    return np.stack([c * loc[..., 0] - si * loc[..., 1], si * loc[..., 0] + c * loc[..., 1]], -1)


# ----------------------------------------------------------------------------------------------
# motion
# ----------------------------------------------------------------------------------------------
_AMP_BY_DEPTH = np.array([0.004, 0.021, 0.036, 0.054, 0.072, 0.085])   # rad
_FREQ_BY_DEPTH = np.array([0.35, 0.5, 0.7, 0.9, 1.1, 1.25])            # Hz


@dataclass
class Motion:
    """Per-branch world transforms x -> A[b, f] @ x + t[b, f] (A (B, F, 3, 3), t (B, F, 3), px),
    dominant sway frequency per branch (B,) Hz, camera offset (F, 2) px. With the wind options:
    swing_deg (B,) swing amplitude of the thinnest branches (deg, 0 on the others); lean (F,) the
    strong gusts' lean of the crown top, share of the tree height, and gusts {"onset", "rise",
    "lean"} (G,) s / s / share of the height."""

    A: np.ndarray
    t: np.ndarray
    branch_freq: np.ndarray
    camera_offset: np.ndarray
    swing_deg: np.ndarray | None = None
    lean: np.ndarray | None = None
    gusts: dict | None = None


def _rodrigues(w: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors w (..., 3)."""
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    k = w / np.maximum(np.linalg.norm(w, axis=-1, keepdims=True), 1e-15)
    z = np.zeros(w.shape[:-1])
    K = np.stack([np.stack([z, -k[..., 2], k[..., 1]], -1),
                  np.stack([k[..., 2], z, -k[..., 0]], -1),
                  np.stack([-k[..., 1], k[..., 0], z], -1)], -2)
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * (K @ K)


def _smooth1d(x: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian smoothing along axis 0 (reflect padding); sigma in samples."""
    if sigma <= 0:
        return x
    r = int(math.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    pad = np.pad(x, [(r, r)] + [(0, 0)] * (x.ndim - 1), mode="reflect")
    cols = pad.reshape(pad.shape[0], -1)
    out = np.stack([np.convolve(cols[:, j], k, mode="valid") for j in range(cols.shape[1])], 1)
    return out.reshape(x.shape)


def _branch_sway(cfg: SynthConfig, tree: Tree, rng: np.random.Generator, t: np.ndarray):
    """Rotation vectors (B, F, 3) of every branch about its base, and dominant freq (B,) Hz."""
    depth = np.minimum(tree.branch_depth, len(_AMP_BY_DEPTH) - 1)
    nb = len(depth)
    f0 = _FREQ_BY_DEPTH[depth] + rng.uniform(-0.08, 0.12, nb)
    ratios = np.stack([np.ones(nb), rng.uniform(1.5, 2.3, nb), rng.uniform(0.45, 0.75, nb)], 1)
    freqs = np.clip(f0[:, None] * ratios * cfg.freq_scale, 0.3, 1.5)
    a0 = _AMP_BY_DEPTH[depth] * cfg.sway_scale * rng.uniform(0.8, 1.2, nb)
    amps = a0[:, None] * np.stack([np.ones(nb), rng.uniform(0.2, 0.45, nb),
                                   rng.uniform(0.15, 0.4, nb)], 1)
    psi = np.pi / 2 + rng.normal(0, 0.6, (nb, 3))
    phase = rng.uniform(0, 2 * np.pi, (nb, 3))
    axes = np.stack([np.cos(psi), np.sin(psi), np.zeros_like(psi)], -1)      # (B, 3, 3)
    wave = amps[..., None] * np.sin(2 * np.pi * freqs[..., None] * t + phase[..., None])
    omega = np.einsum("bkf,bkc->bfc", wave, axes)
    dominant = freqs[np.arange(nb), np.argmax(amps, axis=1)]
    return omega, dominant


def _gust(cfg: SynthConfig, rng: np.random.Generator, t: np.ndarray) -> np.ndarray:
    """Crown gust rotation vectors (F, 3): slow sinusoid (0.1-0.3 Hz) plus smooth noise."""
    fg = rng.uniform(0.1, 0.3)
    knots_dt = 0.8
    n_knots = int(t[-1] / knots_dt) + 3 if len(t) else 3
    knots = rng.standard_normal(n_knots)
    noise = np.interp(t, np.arange(n_knots) * knots_dt, knots)
    noise = _smooth1d(noise, 0.4 * cfg.fps)
    noise = (noise - noise.mean()) / max(noise.std(), 1e-9)
    g = 0.6 * np.sin(2 * np.pi * fg * t + rng.uniform(0, 2 * np.pi)) + 0.45 * noise
    psi = np.pi / 2 + rng.normal(0, 0.25)
    axis = np.array([math.cos(psi), math.sin(psi), 0.0])
    return cfg.gust_rad * g[:, None] * axis


def frame_times(cfg: SynthConfig) -> np.ndarray:
    """Time of every frame since the first (F,) float64 s: ``f / fps``; with ``vfr_header_fps``
    irregular steps (log-normal around 1 / fps, a few gaps of 3-7 steps) whose mean rate is
    ``fps``, in whole milliseconds (what the MKV container stores)."""
    nf = cfg.frames
    if cfg.vfr_header_fps <= 0:
        return np.arange(nf) / cfg.fps
    rng = _rng(cfg, _S_TIMES)
    dt = rng.lognormal(0.0, 0.35, max(nf - 1, 0))
    gap = rng.random(len(dt)) < 0.05
    dt[gap] *= rng.uniform(3.0, 7.0, int(gap.sum()))
    dt = dt / max(dt.mean(), 1e-12) / cfg.fps if len(dt) else dt
    t = np.concatenate([[0.0], np.cumsum(dt)])
    return np.round(t * 1000.0) / 1000.0


def _thin_swing(cfg: SynthConfig, tree: Tree, t: np.ndarray, omega: np.ndarray,
                dominant: np.ndarray) -> np.ndarray:
    """Replace the sway of the thinnest branches (the last order) by a swing of ``thin_swing_deg``
    at ``thin_swing_hz`` about the normal of the plane of the branch and its parent's last
    segment, so the branching angle opens and closes by exactly the swing. Edits ``omega`` (B, F,
    3) and ``dominant`` (B,) in place; returns the amplitude per branch (B,) deg (0 elsewhere)."""
    rng = _rng(cfg, _S_SWING)
    depth = tree.branch_depth
    thin = np.flatnonzero((depth == depth.max()) & (depth >= 1))
    amp = np.zeros(len(depth))
    a = rng.uniform(*cfg.thin_swing_deg, len(thin))
    f = rng.uniform(*cfg.thin_swing_hz, len(thin))
    ph = rng.uniform(0, 2 * np.pi, len(thin))
    for i, b in enumerate(thin):
        base = tree.branch_base[b]
        chord = tree.rest[tree.branch_nodes[b][-1]] - tree.rest[base]
        pseg = tree.rest[base] - tree.rest[tree.parents[base]]
        ax = np.cross(pseg, chord)
        if np.linalg.norm(ax) < 0.05 * np.linalg.norm(pseg) * np.linalg.norm(chord):
            ax = np.cross(chord, np.array([1.0, 0.0, 0.0]))
            if np.linalg.norm(ax) < 1e-6 * np.linalg.norm(chord):
                ax = np.array([0.0, 1.0, 0.0])
        omega[b] = (math.radians(a[i]) * np.sin(2 * np.pi * f[i] * t + ph[i]))[:, None] * _unit(ax)
        dominant[b] = f[i]
        amp[b] = a[i]
    return amp


def crown_top(rest: np.ndarray) -> np.ndarray:
    """Indices of the nodes in the top 10 % of the skeleton's height (rest (N, 3), z up): the
    nodes whose lean the strong gusts are set by."""
    z = rest[:, 2]
    return np.flatnonzero(z >= z.max() - 0.1 * (z.max() - z.min()))


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _lean(cfg: SynthConfig, tree: Tree, t: np.ndarray, leaves: Leaves | None = None) -> dict:
    """Strong gusts: ``gust_count`` events from 1 s on, one after another, each rising within
    ``gust_rise_s`` to a lean of the crown top of ``gust_lean`` x the tree height (smoothstep),
    holding 0.8-2 s (a 5 % wobble), falling back within 1.2-2.5 s. The lean is a rotation about
    +-y (wind along x) split between the trunk (about the root) and the trunk's children (about
    the first split; a palm: its trunk segments alike), scaled so that the mean x displacement of
    :func:`crown_top` is the lean (small angles). Returns {"theta" (F,) rad, "weight" (B,),
    "axis" (3,), "lean" (F,) share of the height, "onset", "rise", "peak" (G,)}."""
    rng = _rng(cfg, _S_LEAN)
    total = float(t[-1]) if len(t) else 0.0
    g_n = max(int(cfg.gust_count), 1)
    t0 = min(1.0, 0.1 * total)
    slot = (total - t0) / g_n
    prof = np.zeros(len(t))
    onset, rise, peak = [], [], []
    for g in range(g_n):
        start = t0 + g * slot
        r = rng.uniform(*cfg.gust_rise_s)
        hold = rng.uniform(0.8, 2.0)
        rel = rng.uniform(1.2, 2.5)
        on = start + rng.uniform(0.0, 0.3) * slot
        avail = start + slot - on
        if r + hold + rel > avail:
            k = max((avail - r) / (hold + rel), 0.2)
            hold, rel = hold * k, rel * k
        lean = rng.uniform(*cfg.gust_lean)
        x = t - on
        wob = 1.0 - 0.025 * (1.0 - np.cos(2 * np.pi * 0.7 * np.clip(x - r, 0, None) + rng.uniform(0, 6.3)))
        up = _smoothstep(x / r)
        down = 1.0 - _smoothstep((x - r - hold) / max(rel, 1e-6))
        prof += lean * up * down * np.where(x > r, wob, 1.0)
        onset.append(on)
        rise.append(r)
        peak.append(lean)
    nb = len(tree.branch_parent)
    w = np.zeros(nb)
    if tree.trunk_branches is not None:
        w[tree.trunk_branches] = 1.0 / len(tree.trunk_branches)
    else:
        w[0] = 0.5
        w[tree.branch_parent == 0] = 0.5
    top = crown_top(tree.rest)
    arm = []
    for n in top:                                     # sum over the node's branch and its ancestors
        b, acc = int(tree.node_branch[n]), 0.0
        while b >= 0:
            acc += w[b] * (tree.rest[n, 2] - tree.rest[tree.branch_base[b], 2])
            b = int(tree.branch_parent[b])
        arm.append(acc)
    k_arm = max(float(np.mean(arm)), 1e-9)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    axis = _unit(np.array([rng.uniform(-0.15, 0.15), sign, 0.0]))
    height = (tree.rest[:, 2] + tree.radius).max()    # the tree's height incl. leaves, at rest
    if leaves is not None and len(leaves.rest):
        height = max(height, float((leaves.rest[:, 2] - leaves.shape[..., 1].min(axis=1)).max()))
    return dict(theta=prof * height / k_arm / abs(axis[1]), weight=w, axis=axis, lean=prof,
                onset=np.array(onset), rise=np.array(rise), peak=np.array(peak))


def _palm_sway(cfg: SynthConfig, tree: Tree, rng: np.random.Generator, t: np.ndarray):
    """Rotation vectors (B, F, 3) and dominant frequency (B,) Hz of a palm: the trunk bends as one
    (every segment the same slow wave, 0.2-0.35 Hz); every frond flaps about the horizontal axis
    across it (some side to side too) at its own 0.5-1.1 Hz, a wave that travels out along the
    chain and grows toward the tip."""
    nb = len(tree.branch_parent)
    omega = np.zeros((nb, len(t), 3))
    dominant = np.zeros(nb)
    ft = rng.uniform(0.2, 0.35) * cfg.freq_scale
    at = 0.006 * cfg.sway_scale
    psi = np.pi / 2 + rng.normal(0, 0.3)
    ax_t = np.array([math.cos(psi), math.sin(psi), 0.0])
    wave_t = at * (np.sin(2 * np.pi * ft * t + rng.uniform(0, 6.3))
                   + 0.4 * np.sin(2 * np.pi * 1.7 * ft * t + rng.uniform(0, 6.3)))
    for b in tree.trunk_branches:
        omega[b] = wave_t[:, None] * ax_t
        dominant[b] = ft
    for chain in tree.frond_branches:
        d0 = tree.rest[tree.branch_nodes[chain[0]][-1]] - tree.rest[tree.branch_base[chain[0]]]
        h = np.array([d0[0], d0[1], 0.0])
        h = _unit(h) if np.linalg.norm(h) > 1e-6 else np.array([1.0, 0.0, 0.0])
        flap = np.cross(_UP, h)
        ax = _unit(flap + rng.uniform(-0.5, 0.5) * _UP)
        f = rng.uniform(0.5, 1.1) * cfg.freq_scale
        a = rng.uniform(0.02, 0.035) * cfg.sway_scale
        ph = rng.uniform(0, 2 * np.pi)
        ph2 = rng.uniform(0, 2 * np.pi)
        n_s = len(chain)
        for k, b in enumerate(chain):
            ak = a * (0.6 + 0.8 * k / n_s)
            wave = ak * (np.sin(2 * np.pi * f * t + ph - 0.35 * k)
                         + 0.3 * np.sin(2 * np.pi * 2.1 * f * t + ph2 - 0.5 * k))
            omega[b] = wave[:, None] * ax
            dominant[b] = f
    return omega, dominant


def _camera_offsets(cfg: SynthConfig, rng: np.random.Generator) -> np.ndarray:
    """Image-space camera translation per frame (F, 2) px, zero at frame 0."""
    nf = cfg.frames
    off = np.zeros((nf, 2))
    s = _scale(cfg)
    if cfg.shake_px > 0:
        sh = _smooth1d(rng.standard_normal((nf, 2)), 1.2)
        off += sh / max(sh.std(), 1e-9) * cfg.shake_px * s
    if cfg.drift_px > 0:
        ang = rng.uniform(0, 2 * np.pi)
        ramp = np.arange(nf) / max(nf - 1, 1)
        wob = 0.25 * np.sin(2 * np.pi * 0.07 * np.arange(nf) / cfg.fps + rng.uniform(0, 6.3))
        off += (cfg.drift_px * s * (ramp + wob))[:, None] * np.array([math.cos(ang), math.sin(ang)])
    return off - off[:1]


def simulate(cfg: SynthConfig, tree: Tree, leaves: Leaves | None = None) -> Motion:
    """Forward kinematics of the swaying tree for all frames (``leaves``: for the tree's height
    that the strong gusts' lean is a share of)."""
    rng = _rng(cfg, _S_MOTION)
    nf = cfg.frames
    t = frame_times(cfg)
    if cfg.kind == "palm":
        omega, dominant = _palm_sway(cfg, tree, rng, t)
    else:
        omega, dominant = _branch_sway(cfg, tree, rng, t)
    gust = _rodrigues(_gust(cfg, rng, t)) if cfg.gust_rad > 0 else None
    swing = None
    if cfg.thin_swing_deg[1] > 0 and cfg.kind != "palm":
        swing = _thin_swing(cfg, tree, t, omega, dominant)
    lean = _lean(cfg, tree, t, leaves) if cfg.gust_lean[1] > 0 else None
    nb = len(tree.branch_parent)
    A = np.empty((nb, nf, 3, 3))
    T = np.empty((nb, nf, 3))
    eye = np.broadcast_to(np.eye(3), (nf, 3, 3))
    zero = np.zeros((nf, 3))
    for b in range(nb):                                   # parents precede children
        R = _rodrigues(omega[b])
        par = tree.branch_parent[b]
        if par == 0 and gust is not None:
            R = gust @ R
        if lean is not None and lean["weight"][b] > 0:
            R = _rodrigues((lean["theta"] * lean["weight"][b])[:, None] * lean["axis"]) @ R
        Ap, tp = (eye, zero) if par < 0 else (A[par], T[par])
        p = tree.rest[tree.branch_base[b]]
        A[b] = Ap @ R
        T[b] = np.einsum("fij,fj->fi", Ap, p - R @ p) + tp
    return Motion(A=A, t=T, branch_freq=dominant,
                  camera_offset=_camera_offsets(cfg, _rng(cfg, _S_CAMERA)), swing_deg=swing,
                  lean=None if lean is None else lean["lean"],
                  gusts=None if lean is None else {k: lean[k] for k in ("onset", "rise", "peak")})


def node_positions(tree: Tree, motion: Motion) -> np.ndarray:
    """World positions of all nodes per frame (F, N, 3) px."""
    nb = tree.node_branch
    return (np.einsum("nfij,nj->fni", motion.A[nb], tree.rest)
            + motion.t[nb].transpose(1, 0, 2))


# ----------------------------------------------------------------------------------------------
# static background, occluder
# ----------------------------------------------------------------------------------------------
def _noise_field(rng: np.random.Generator, h: int, w: int, cells: tuple) -> np.ndarray:
    """Smooth random field (h, w) float32 in ~[0, 1] from a cells=(ny, nx) grid."""
    g = rng.random((cells[0] + 2, cells[1] + 2)).astype(np.float32)
    big = cv2.resize(g, (w + 2 * w // cells[1], h + 2 * h // cells[0]), interpolation=cv2.INTER_CUBIC)
    oy, ox = h // cells[0], w // cells[1]
    return np.clip(big[oy:oy + h, ox:ox + w], 0, 1)


def _bark_base_colors(bark: str) -> tuple[np.ndarray, np.ndarray]:
    """BGR bark colour at the root and on thin twigs."""
    if bark == "grey":
        return np.array([74.0, 78.0, 78.0]), np.array([100.0, 104.0, 104.0])
    return np.array([42.0, 70.0, 100.0]), np.array([82.0, 92.0, 104.0])


def render_background(cfg: SynthConfig) -> np.ndarray:
    """Static background (H, W, 3) uint8: sky, clouds, hills, ground, fence, roof, rock."""
    rng = _rng(cfg, _S_BACKGROUND)
    h, w, s = cfg.height, cfg.width, _scale(cfg)
    gv = int(round(cfg.ground_frac * h))
    rows = np.arange(h, dtype=np.float32)[:, None, None]
    tt = np.clip(rows / max(gv, 1), 0, 1) ** 0.8
    top, low = ((196, 138, 78), (236, 224, 208)) if cfg.sky == "blue" else ((226, 224, 221), (240, 240, 238))
    sky = np.array(top, np.float32) * (1 - tt) + np.array(low, np.float32) * tt
    img = np.broadcast_to(sky, (h, w, 3)).copy()
    cloud = 0.65 * _noise_field(rng, h, w, (3, 5)) + 0.35 * _noise_field(rng, h, w, (8, 12))
    cloud = np.clip((cloud - 0.55) / 0.25, 0, 1)[..., None] * (1 - tt) ** 0.4 * 0.85
    img = img * (1 - cloud) + np.float32(246) * cloud
    sky_only = img.copy()
    xs = np.arange(w)
    knots = rng.random(12)
    hill_top = gv - h * (0.03 + 0.05 * np.interp(xs, np.linspace(0, w - 1, 12), knots))
    hill = (rows[..., 0] >= hill_top[None, :]) & (rows[..., 0] < gv)
    shade = 0.9 + 0.2 * _noise_field(rng, h, w, (6, 20))
    hill_col = np.array([128, 142, 118], np.float32) * shade[..., None]
    img[hill] = hill_col[hill]
    ground = np.broadcast_to(rows[..., 0] >= gv, (h, w))
    mix = _noise_field(rng, h, w, (4, 6))[..., None]
    fine = _noise_field(rng, h, w, (h // 6, w // 6))[..., None]
    gcol = (np.array([52, 118, 88], np.float32) * (1 - mix) + np.array([58, 92, 118], np.float32) * mix)
    gcol = gcol * (0.8 + 0.35 * fine)
    img[ground] = gcol[ground]
    img += rng.normal(0, 2.0, img.shape).astype(np.float32)
    img = np.clip(img, 0, 255).astype(np.uint8)
    _draw_grass(img, rng, gv, s)
    _draw_fence(img, rng, gv, s)
    _draw_house(img, gv, s)
    _draw_rock(img, rng, gv, s)
    if cfg.light == "backlit":         # against the light everything but the sky is in shadow
        shade = hill | ground | (np.abs(img.astype(np.float32) - sky_only).max(2) > 12)
        img[shade] = (img[shade] * (2 * BACKLIT_GAIN)).astype(np.uint8)
    return img


def _draw_grass(img: np.ndarray, rng: np.random.Generator, gv: int, s: float) -> None:
    """Short anti-aliased grass strokes below the ground line (gv = ground row, s = px scale)."""
    h, w = img.shape[:2]
    n = int(300 * s * s)
    x = rng.uniform(0, w, n)
    y = rng.uniform(gv + 2, h, n)
    ln = rng.uniform(2, 6, n) * s
    lean = rng.normal(0, 0.4, n)
    cols = rng.uniform(0.6, 1.3, n)
    for i in range(n):
        c = tuple(float(v) for v in np.clip(np.array([45, 115, 80]) * cols[i], 0, 255))
        p0 = (int(x[i] * _SUB), int(y[i] * _SUB))
        p1 = (int((x[i] + lean[i] * ln[i]) * _SUB), int((y[i] - ln[i]) * _SUB))
        cv2.line(img, p0, p1, c, 1, cv2.LINE_AA, _SHIFT)


def _poly(img: np.ndarray, pts, color, aa: bool = True) -> None:
    cv2.fillConvexPoly(img, np.rint(np.asarray(pts, float) * _SUB).astype(np.int32),
                       tuple(float(c) for c in color), cv2.LINE_AA if aa else cv2.LINE_8, _SHIFT)


def _draw_fence(img: np.ndarray, rng: np.random.Generator, gv: int, s: float) -> None:
    """Three brown (bark-coloured) wooden posts with rails near the left edge."""
    h, w = img.shape[:2]
    brown = _bark_base_colors("brown")[0]
    xs = [w * (0.035 + 0.055 * i) for i in range(3)]
    pw = max(3.0, 0.016 * w)
    top = gv - 0.13 * h
    for y in (top + 0.25 * (gv - top), top + 0.65 * (gv - top)):
        _poly(img, [(xs[0], y), (xs[-1] + pw, y), (xs[-1] + pw, y + 2.5 * s), (xs[0], y + 2.5 * s)],
              brown * 0.95)
    for x in xs:
        t0 = top - rng.uniform(0, 0.015 * h)
        _poly(img, [(x, t0), (x + pw, t0), (x + pw, gv + 0.03 * h), (x, gv + 0.03 * h)],
              brown * rng.uniform(0.9, 1.1))
        _poly(img, [(x + 0.6 * pw, t0), (x + pw, t0), (x + pw, gv + 0.03 * h),
                    (x + 0.6 * pw, gv + 0.03 * h)], brown * 0.7)
        for _ in range(int(6 * s)):
            yy = rng.uniform(t0 + 2, gv)
            xx = x + rng.uniform(0.15, 0.75) * pw
            _poly(img, [(xx, yy), (xx + 1.0 * s, yy), (xx + 1.0 * s, yy + 4 * s), (xx, yy + 4 * s)],
                  brown * 0.55)


def _draw_house(img: np.ndarray, gv: int, s: float) -> None:
    """A small house with a brown shingled roof near the right edge."""
    h, w = img.shape[:2]
    x0, x1 = 0.84 * w, 0.975 * w
    wall_top = gv - 0.085 * h
    _poly(img, [(x0, wall_top), (x1, wall_top), (x1, gv + 1), (x0, gv + 1)], (178, 190, 204))
    _poly(img, [(x0 + 0.25 * (x1 - x0), wall_top + 0.3 * (gv - wall_top)),
                (x0 + 0.45 * (x1 - x0), wall_top + 0.3 * (gv - wall_top)),
                (x0 + 0.45 * (x1 - x0), wall_top + 0.7 * (gv - wall_top)),
                (x0 + 0.25 * (x1 - x0), wall_top + 0.7 * (gv - wall_top))], (70, 60, 52))
    roof_h = 0.07 * h
    roof = np.array([(x0 - 4 * s, wall_top), (x1 + 4 * s, wall_top),
                     (x1 - 0.02 * w, wall_top - roof_h), (x0 + 0.02 * w, wall_top - roof_h)])
    roof_col = np.array([46.0, 68.0, 98.0])
    _poly(img, roof, roof_col)
    for k in range(1, 5):
        y = wall_top - roof_h * k / 5
        frac = k / 5
        xa = roof[0, 0] + (roof[3, 0] - roof[0, 0]) * frac
        xb = roof[1, 0] + (roof[2, 0] - roof[1, 0]) * frac
        cv2.line(img, (int(xa * _SUB), int(y * _SUB)), (int(xb * _SUB), int(y * _SUB)),
                 tuple(float(c) for c in roof_col * 0.6), 1, cv2.LINE_AA, _SHIFT)
        for xx in np.arange(xa + (k % 2) * 3 * s, xb, 6 * s):
            cv2.line(img, (int(xx * _SUB), int(y * _SUB)),
                     (int(xx * _SUB), int((y + roof_h / 5) * _SUB)),
                     tuple(float(c) for c in roof_col * 0.7), 1, cv2.LINE_AA, _SHIFT)


def _draw_rock(img: np.ndarray, rng: np.random.Generator, gv: int, s: float) -> None:
    """A grey-brown rock on the ground, right of the tree."""
    h, w = img.shape[:2]
    c = (int(0.76 * w * _SUB), int((gv + 0.045 * h) * _SUB))
    axes = (int(0.035 * w * _SUB), int(0.022 * h * _SUB))
    cv2.ellipse(img, c, axes, 0, 180, 360, (88, 96, 108), -1, cv2.LINE_AA, _SHIFT)
    cv2.ellipse(img, c, axes, 0, 0, 180, (60, 66, 76), -1, cv2.LINE_AA, _SHIFT)
    for _ in range(int(8 * s)):
        px = c[0] / _SUB + rng.uniform(-0.7, 0.7) * axes[0] / _SUB
        py = c[1] / _SUB + rng.uniform(-0.7, 0.2) * axes[1] / _SUB
        cv2.circle(img, (int(px * _SUB), int(py * _SUB)), int(1.2 * s * _SUB),
                   (55, 60, 70), -1, cv2.LINE_AA, _SHIFT)


@dataclass
class Occluder:
    """Person-like sprite (h, w, 3) uint8 + alpha (h, w) bool; top-left x per frame (F,) int in
    frame-1 coordinates (active: (F,) bool); top y int."""

    sprite: np.ndarray
    alpha: np.ndarray
    x0: np.ndarray
    y0: int
    active: np.ndarray


def build_occluder(cfg: SynthConfig) -> Occluder | None:
    """Dark textured person walking across the lower trunk during ~25%-70% of the clip."""
    if not cfg.occluder:
        return None
    rng = _rng(cfg, _S_CAMERA, 1)
    ho = int(round(cfg.height / 6))
    wo = int(round(0.42 * ho))
    spr = np.zeros((ho, wo, 3), np.uint8)
    alpha = np.zeros((ho, wo), np.uint8)
    for tgt, val in ((spr, None), (alpha, 255)):
        def col(c, val=val):
            return val if val is not None else c
        cv2.circle(tgt, (wo // 2, int(0.1 * ho)), int(0.09 * ho), col((40, 52, 70)), -1)
        cv2.rectangle(tgt, (int(0.12 * wo), int(0.19 * ho)), (int(0.88 * wo), int(0.6 * ho)),
                      col((52, 44, 40)), -1)
        cv2.rectangle(tgt, (0, int(0.22 * ho)), (int(0.12 * wo), int(0.55 * ho)), col((45, 40, 38)), -1)
        cv2.rectangle(tgt, (int(0.88 * wo), int(0.22 * ho)), (wo - 1, int(0.55 * ho)),
                      col((45, 40, 38)), -1)
        cv2.rectangle(tgt, (int(0.18 * wo), int(0.6 * ho)), (int(0.46 * wo), ho - 1), col((30, 30, 34)), -1)
        cv2.rectangle(tgt, (int(0.54 * wo), int(0.6 * ho)), (int(0.82 * wo), ho - 1), col((30, 30, 34)), -1)
    for k in range(4):                                  # shirt stripes and a light badge: corners
        y = int((0.24 + 0.09 * k) * ho)
        cv2.rectangle(spr, (int(0.12 * wo), y), (int(0.88 * wo), y + max(1, int(0.03 * ho))),
                      (90, 96, 110), -1)
    cv2.rectangle(spr, (int(0.55 * wo), int(0.42 * ho)), (int(0.75 * wo), int(0.52 * ho)),
                  (150, 160, 170), -1)
    nf = cfg.frames
    f0, f1 = int(0.25 * nf), int(0.7 * nf)
    active = np.zeros(nf, bool)
    active[f0:f1 + 1] = True
    prog = np.clip((np.arange(nf) - f0) / max(f1 - f0, 1), 0, 1)
    path = -wo + prog * (cfg.width + wo)
    if rng.random() < 0.5:
        path = cfg.width - wo - path
    y0 = int(round(cfg.ground_frac * cfg.height + 0.05 * cfg.height)) - ho
    y0 = min(y0, cfg.height - ho)
    return Occluder(sprite=spr, alpha=alpha > 0, x0=np.rint(path).astype(int), y0=y0, active=active)


def _paste_occluder(img: np.ndarray, occ: Occluder, f: int, value=None) -> None:
    """Paste the occluder sprite of frame f (frame-1 coords) into img (colour or label value)."""
    if occ is None or not occ.active[f]:
        return
    h, w = img.shape[:2]
    ho, wo = occ.alpha.shape
    x0, y0 = int(occ.x0[f]), occ.y0
    xa, xb, ya, yb = max(x0, 0), min(x0 + wo, w), max(y0, 0), min(y0 + ho, h)
    if xa >= xb or ya >= yb:
        return
    a = occ.alpha[ya - y0:yb - y0, xa - x0:xb - x0]
    region = img[ya:yb, xa:xb]
    region[a] = value if value is not None else occ.sprite[ya - y0:yb - y0, xa - x0:xb - x0][a]


def occluder_boxes(cfg: SynthConfig, occ: Occluder | None, camera_offset: np.ndarray) -> np.ndarray:
    """(F, 4) x0, y0, x1, y1 of the occluder as seen in the image (incl. camera offset, clipped
    to the frame); -1 where it is absent or outside."""
    boxes = -np.ones((cfg.frames, 4), np.float32)
    if occ is None:
        return boxes
    ho, wo = occ.alpha.shape
    for f in range(cfg.frames):
        if not occ.active[f]:
            continue
        dx, dy = camera_offset[f]
        x0, y0 = occ.x0[f] + dx, occ.y0 + dy
        b = np.array([max(x0, 0), max(y0, 0), min(x0 + wo, cfg.width), min(y0 + ho, cfg.height)])
        if b[2] > b[0] and b[3] > b[1]:
            boxes[f] = b
    return boxes


@dataclass
class Light:
    """Lighting that changes over the clip: gain (F,) global multiplier; shadow (Hf, Wf) float32
    darkness 0..1 of the cloud-shadow field (None without shadows), its velocity (2,) px/s across
    the frame, depth (darkening at darkness 1) and the crop's top-left at t = 0 (2,) px."""

    gain: np.ndarray
    shadow: np.ndarray | None
    velocity: np.ndarray
    depth: float
    origin: np.ndarray


def build_light(cfg: SynthConfig, times: np.ndarray) -> Light | None:
    """Flicker (``flicker``: gain 1 +- flicker, 65 % of its std a slow part below 0.5 Hz, 35 % a
    fast part at 2.5-8 Hz, scaled to span exactly [1 - flicker, 1 + flicker]) and drifting cloud
    shadows (``cloud_shadow``: soft blobs ~1/3 of the frame height, 12-25 px/s @360)."""
    if cfg.flicker <= 0 and cfg.cloud_shadow <= 0:
        return None
    rng = _rng(cfg, _S_LIGHT)
    total = float(times[-1]) if len(times) else 0.0
    gain = np.ones(len(times))
    if cfg.flicker > 0 and len(times) > 1:
        knots = rng.standard_normal(int(total / 1.5) + 3)
        slow = (0.6 * np.sin(2 * np.pi * rng.uniform(0.1, 0.3) * times + rng.uniform(0, 6.3))
                + 0.4 * np.interp(times, np.arange(len(knots)) * 1.5, knots))
        fast = sum(rng.uniform(0.5, 1.0) * np.sin(2 * np.pi * rng.uniform(2.5, 8.0) * times + rng.uniform(0, 6.3))
                   for _ in range(3))
        c = (0.65 * (slow - slow.mean()) / max(slow.std(), 1e-9)
             + 0.35 * (fast - fast.mean()) / max(fast.std(), 1e-9))
        gain = 1.0 + cfg.flicker * (2.0 * (c - c.min()) / max(np.ptp(c), 1e-9) - 1.0)
    shadow, vel, origin = None, np.zeros(2), np.zeros(2)
    if cfg.cloud_shadow > 0:
        s = _scale(cfg)
        vel = np.array([(1 if rng.random() < 0.5 else -1) * rng.uniform(12.0, 25.0), rng.uniform(-4.0, 4.0)]) * s
        pad = int(math.ceil(0.1 * cfg.height))
        travel = np.abs(vel) * total
        wf = int(cfg.width + travel[0] + 2 * pad) + 2
        hf = int(cfg.height + travel[1] + 2 * pad) + 2
        blob = cfg.height / 3.0
        field = _noise_field(rng, hf, wf, (max(2, int(round(hf / blob))), max(2, int(round(wf / blob)))))
        shadow = _smoothstep((field - 0.45) / 0.25).astype(np.float32)
        origin = pad + np.maximum(vel, 0.0) * total
    return Light(gain=gain, shadow=shadow, velocity=vel, depth=float(cfg.cloud_shadow), origin=origin)


def light_multiplier(scene: Scene, f: int) -> np.ndarray:
    """(H, W) float32 factor frame f's colours are multiplied by (gain x cloud shadows); 1 without light."""
    cfg, lt = scene.cfg, scene.light
    if lt is None:
        return np.ones((cfg.height, cfg.width), np.float32)
    m = np.full((cfg.height, cfg.width), np.float32(lt.gain[f]), np.float32)
    if lt.shadow is not None:
        x0, y0 = lt.origin - lt.velocity * scene.times[f]
        crop = cv2.getRectSubPix(lt.shadow, (cfg.width, cfg.height),
                                 (float(x0 + (cfg.width - 1) / 2.0), float(y0 + (cfg.height - 1) / 2.0)))
        m *= np.float32(1.0) - np.float32(lt.depth) * crop
    return m


@dataclass
class Foreground:
    """A blurred branch close to the camera, hanging from ``pivot`` (2,) px above the frame and
    swinging by ``angle`` (F,) rad. Shapes in the branch's own frame (y along the limb, px):
    quads (Q, 4, 2) bark, ellipses (E, 5) cx, cy, ax, ay, deg of leaves; colours; blur sigma px."""

    pivot: np.ndarray
    angle: np.ndarray
    quads: np.ndarray
    quad_color: list
    ellipses: np.ndarray
    ellipse_color: list
    sigma: float


def build_foreground(cfg: SynthConfig, tree: Tree, times: np.ndarray) -> Foreground | None:
    """A branch in front of the crown: hangs from 25-45 % of the frame height above the frame,
    reaches 60-85 % down the crown, swings at 0.15-0.28 Hz between 50-65 % of the crown's width
    left and right of its centre (at the crown's middle height), starting at one side."""
    if not cfg.foreground:
        return None
    rng = _rng(cfg, _S_FOREGROUND)
    h = cfg.height
    cx, gv = cfg.width / 2.0, cfg.ground_frac * cfg.height
    crown = tree.rest[tree.depth_level >= 1] if (tree.depth_level >= 1).any() else tree.rest
    u, v = cx + crown[:, 0], gv - crown[:, 2]
    u0, u1, v0, v1 = u.min(), u.max(), v.min(), v.max()
    wc = u1 - u0
    pivot = np.array([0.5 * (u0 + u1) + rng.uniform(-0.1, 0.1) * wc, -rng.uniform(0.25, 0.45) * h])
    v_tip = v0 + rng.uniform(0.6, 0.85) * (v1 - v0)
    length = v_tip - pivot[1]
    v_mid = 0.5 * (v0 + v1)
    amp = math.atan(rng.uniform(0.5, 0.65) * wc / (v_mid - pivot[1]))
    freq = rng.uniform(0.15, 0.28)
    side = 1.0 if rng.random() < 0.5 else -1.0
    angle = -side * amp * np.cos(2 * np.pi * freq * times) + 0.08 * amp * np.sin(2 * np.pi * 0.9 * times
                                                                                 + rng.uniform(0, 6.3))
    w0 = 0.045 * h * rng.uniform(0.8, 1.2)
    sk = np.linspace(0.0, 1.0, 9)
    curv = rng.uniform(-1.0, 1.0) * 0.06 * length
    pts = np.stack([curv * np.sin(np.pi * sk), sk * length], 1)
    hw = 0.5 * w0 * (1.0 - 0.55 * sk)
    quads, ells = [], []

    def strip(p, half):
        d = _unit(np.diff(p, axis=0))
        nrm = np.stack([-d[:, 1], d[:, 0]], 1)
        for i in range(len(p) - 1):
            quads.append([p[i] + nrm[i] * half[i], p[i + 1] + nrm[i] * half[i + 1],
                          p[i + 1] - nrm[i] * half[i + 1], p[i] - nrm[i] * half[i]])

    strip(pts, hw)
    for _ in range(int(rng.integers(4, 7))):
        st = rng.uniform(0.4, 0.95)
        a0 = np.interp(st, sk, pts[:, 0]), st * length
        ang = np.radians(rng.uniform(25, 60)) * (1 if rng.random() < 0.5 else -1)
        tl = rng.uniform(0.1, 0.22) * length
        tip = np.array([a0[0] + math.sin(ang) * tl, a0[1] + math.cos(ang) * tl])
        tw = 0.3 * float(np.interp(st, sk, hw))
        strip(np.array([a0, 0.5 * (np.array(a0) + tip), tip]), np.array([tw, 0.8 * tw, 0.5 * tw]))
        for _ in range(int(rng.integers(2, 4))):
            c = tip + rng.normal(0, 0.02 * h, 2)
            ells.append([c[0], c[1], rng.uniform(0.025, 0.05) * h, rng.uniform(0.015, 0.03) * h,
                         rng.uniform(0, 180)])
    for st in rng.uniform(0.55, 1.0, int(rng.integers(3, 6))):
        c = np.array([np.interp(st, sk, pts[:, 0]), st * length]) + rng.normal(0, 0.02 * h, 2)
        ells.append([c[0], c[1], rng.uniform(0.025, 0.05) * h, rng.uniform(0.015, 0.03) * h, rng.uniform(0, 180)])
    bark = np.array([38.0, 46.0, 54.0])
    leaf = np.array([34.0, 74.0, 46.0])
    return Foreground(pivot=pivot, angle=angle, quads=np.array(quads, float),
                      quad_color=[tuple(float(x) for x in bark * rng.uniform(0.85, 1.15)) for _ in quads],
                      ellipses=np.array(ells, float),
                      ellipse_color=[tuple(float(x) for x in np.clip(leaf * rng.uniform(0.8, 1.3), 0, 255))
                                     for _ in ells],
                      sigma=float(rng.uniform(0.010, 0.016) * h))


def _foreground_layer(cfg: SynthConfig, fg: Foreground, f: int):
    """Blurred foreground of frame f in frame-1 coordinates: (premultiplied colour (h, w, 3),
    alpha (h, w)) float32 of a box, and the box's (x0, y0); None when it is outside the frame."""
    c, s_ = math.cos(fg.angle[f]), math.sin(fg.angle[f])
    R = np.array([[c, -s_], [s_, c]])
    quads = fg.quads @ R.T + fg.pivot
    ell = fg.ellipses.copy()
    ell[:, :2] = ell[:, :2] @ R.T + fg.pivot
    pad = 3.0 * fg.sigma + 2.0
    pts = np.concatenate([quads.reshape(-1, 2), ell[:, :2] - ell[:, 2:3], ell[:, :2] + ell[:, 2:3]])
    x0 = int(max(math.floor(pts[:, 0].min() - pad), 0))
    y0 = int(max(math.floor(pts[:, 1].min() - pad), 0))
    x1 = int(min(math.ceil(pts[:, 0].max() + pad), cfg.width))
    y1 = int(min(math.ceil(pts[:, 1].max() + pad), cfg.height))
    if x1 <= x0 or y1 <= y0:
        return None
    col = np.zeros((y1 - y0, x1 - x0, 3), np.uint8)
    alpha = np.zeros((y1 - y0, x1 - x0), np.uint8)
    off = np.array([x0, y0], float)
    for q, qc in zip(quads, fg.quad_color):
        qi = np.rint((q - off) * _SUB).astype(np.int32)
        cv2.fillConvexPoly(col, qi, qc, cv2.LINE_AA, _SHIFT)
        cv2.fillConvexPoly(alpha, qi, 255, cv2.LINE_AA, _SHIFT)
    for e, ec in zip(ell, fg.ellipse_color):
        cen = (int(round((e[0] - x0) * _SUB)), int(round((e[1] - y0) * _SUB)))
        axes = (int(round(e[2] * _SUB)), int(round(e[3] * _SUB)))
        ang = float(e[4] + math.degrees(fg.angle[f]))
        cv2.ellipse(col, cen, axes, ang, 0, 360, ec, -1, cv2.LINE_AA, _SHIFT)
        cv2.ellipse(alpha, cen, axes, ang, 0, 360, 255, -1, cv2.LINE_AA, _SHIFT)
    a = alpha.astype(np.float32) / 255.0
    pm = cv2.GaussianBlur(col.astype(np.float32) * a[..., None], (0, 0), fg.sigma)
    a = cv2.GaussianBlur(a, (0, 0), fg.sigma)
    return pm, a, (x0, y0)


#: share of a pixel the foreground branch must cover to be in its mask and its label (at 3 %, a pixel
#: outside the mask differs by less than ~6 levels from the frame without the branch)
FOREGROUND_ALPHA = 0.03


def foreground_mask(scene: Scene, f: int, threshold: float = FOREGROUND_ALPHA) -> np.ndarray:
    """(H, W) bool where the foreground branch covers at least ``threshold`` of frame f's pixel,
    in image coordinates (with the camera's offset); all False without a foreground."""
    cfg = scene.cfg
    m = np.zeros((cfg.height, cfg.width), bool)
    if scene.foreground is None:
        return m
    layer = _foreground_layer(cfg, scene.foreground, f)
    if layer is None:
        return m
    _, a, (x0, y0) = layer
    m[y0:y0 + a.shape[0], x0:x0 + a.shape[1]] = a >= threshold
    dx, dy = scene.motion.camera_offset[f]
    if dx != 0 or dy != 0:
        M = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
        m = cv2.warpAffine(m.astype(np.uint8), M, (cfg.width, cfg.height), flags=cv2.INTER_NEAREST) > 0
    return m


def _paste_foreground(img: np.ndarray, scene: Scene, f: int) -> None:
    layer = _foreground_layer(scene.cfg, scene.foreground, f)
    if layer is None:
        return
    pm, a, (x0, y0) = layer
    region = img[y0:y0 + a.shape[0], x0:x0 + a.shape[1]]
    out = region.astype(np.float32) * (1.0 - a[..., None]) + pm
    region[:] = np.clip(out + 0.5, 0, 255).astype(np.uint8)


# ----------------------------------------------------------------------------------------------
# scene = everything needed to render a frame
# ----------------------------------------------------------------------------------------------
@dataclass
class Scene:
    """Precomputed scene: config, tree, leaves, motion, nodes3d (F, N, 3), background, draw plan."""

    cfg: SynthConfig
    tree: Tree
    leaves: Leaves
    motion: Motion
    nodes3d: np.ndarray
    background: np.ndarray
    occluder: Occluder | None
    cx: float
    ground_v: float
    seg_parent: np.ndarray      # (S,) segment start node
    seg_child: np.ndarray       # (S,) segment end node (= node index of the segment's child)
    seg_r0: np.ndarray          # (S,) px radius at start
    seg_r1: np.ndarray          # (S,) px radius at end
    seg_color: list             # S BGR tuples
    seg_dark: list
    seg_light: list
    marks: dict                 # bark marks: seg, s, w, half_len, half_wid, along (M,) + color
    layers: list                # far to near: dicts of index arrays
    times: np.ndarray | None = None            # (F,) s of every frame (frame_times)
    light: Light | None = None                 # flicker and cloud shadows
    foreground: Foreground | None = None       # blurred branch in front of the tree


def project(cfg_or_scene, xyz: np.ndarray) -> np.ndarray:
    """Orthographic projection (..., 3) world px -> (..., 2) frame-1 pixels."""
    sc = cfg_or_scene
    cx = sc.cx if isinstance(sc, Scene) else sc.width / 2.0
    gv = sc.ground_v if isinstance(sc, Scene) else sc.ground_frac * sc.height
    return np.stack([cx + xyz[..., 0], gv - xyz[..., 2]], axis=-1)


def _segments(tree: Tree):
    """Segment endpoints and radii: one segment per non-root node."""
    child = np.arange(1, len(tree.rest))
    par = tree.parents[child]
    first = tree.node_branch[par] != tree.node_branch[child]
    first |= par == 0
    r1 = tree.radius[child]
    r0 = np.where(first, tree.branch_base_radius[tree.node_branch[child]], tree.radius[par])
    r0 = np.where(par == 0, tree.radius[0], r0)
    return par, child, r0, r1


def _bark_colors(cfg: SynthConfig, tree: Tree, child: np.ndarray, rng: np.random.Generator):
    """Base, shadow and highlight BGR colour lists per segment."""
    root_c, thin_c = _bark_base_colors(cfg.bark)
    m = np.clip(tree.depth_level[child] / 4.0, 0, 1) * 0.85
    tint = rng.uniform(0.92, 1.08, len(tree.branch_parent))[tree.node_branch[child]]
    base = (root_c * (1 - m[:, None]) + thin_c * m[:, None]) * tint[:, None]
    if cfg.kind == "conifer":
        base *= 0.82                                    # dark spruce bark vs dark needles
    if tree.part is not None:                           # a palm's fronds: green-yellow rachis
        base[tree.part[child] == 1] = np.array([70.0, 132.0, 118.0])
    dark = np.clip(base * 0.66, 0, 255)
    light = np.clip(base * 1.22, 0, 255)
    to_list = lambda a: [tuple(float(v) for v in c) for c in a]          # noqa: E731
    return to_list(np.clip(base, 0, 255)), to_list(dark), to_list(light)


def _bark_marks(cfg: SynthConfig, tree: Tree, par, child, r0, r1, base_color: list,
                rng: np.random.Generator) -> dict:
    """Random cracks (along) and bands (across) on thick segments, in segment coordinates."""
    s = _scale(cfg)
    base_color = np.array(base_color, float)
    seg_len = np.linalg.norm(tree.rest[child] - tree.rest[par], axis=1)
    rmean = 0.5 * (r0 + r1)
    thick = np.minimum(r0, r1) >= 1.8
    lam = np.where(thick, seg_len * 2 * rmean / (28.0 * s * s), 0.0)
    cnt = rng.poisson(lam)
    seg = np.repeat(np.arange(len(child)), cnt)
    m = len(seg)
    along = rng.random(m) < 0.7
    half_len = np.where(along, rng.uniform(1.5, 3.5, m), rng.uniform(0.35, 0.7, m)) * s
    half_wid = np.where(along, rng.uniform(0.35, 0.6, m) * s, rng.uniform(0.4, 0.8, m) * rmean[seg])
    light = rng.random(m) < 0.15
    fac = np.where(light, rng.uniform(1.15, 1.35, m), rng.uniform(0.5, 0.72, m))
    col = np.clip(base_color[seg] * fac[:, None], 0, 255)
    return dict(seg=seg, s=rng.uniform(0.05, 0.95, m), w=rng.uniform(-0.75, 0.75, m),
                half_len=half_len, half_wid=half_wid, along=along,
                color=[tuple(float(v) for v in c) for c in col])


def _draw_plan(tree: Tree, leaves: Leaves, par, child, r0, r1, marks) -> list:
    """Assign segments, joints, marks and leaves to depth layers; list ordered far to near."""
    seg_y = 0.5 * (tree.rest[par, 1] + tree.rest[child, 1])
    ys = np.concatenate([seg_y, leaves.rest[:, 1]])
    lo, hi = ys.min(), ys.max() + 1e-6

    def layer_of(y):
        return np.clip(((y - lo) / (hi - lo) * _N_LAYERS).astype(int), 0, _N_LAYERS - 1)

    seg_l = layer_of(seg_y)
    leaf_l = layer_of(leaves.rest[:, 1])
    thin = np.maximum(r0, r1) < 0.8
    shaded = np.minimum(r0, r1) >= 1.5
    joint = (tree.radius[child] >= 0.8)
    plan = []
    for k in range(_N_LAYERS - 1, -1, -1):
        in_k = seg_l == k
        plan.append(dict(thin=np.nonzero(in_k & thin)[0], thick=np.nonzero(in_k & ~thin)[0],
                         joints=np.nonzero(in_k & joint)[0], shaded=np.nonzero(in_k & shaded)[0],
                         marks=np.nonzero(in_k[marks["seg"]])[0],
                         leaves=np.nonzero(leaf_l == k)[0]))
    return plan


def build_scene(cfg: SynthConfig) -> Scene:
    """Build tree, foliage, motion, background and draw lists for ``cfg``."""
    _validate(cfg)
    tree = build_tree(cfg)
    leaves = build_leaves(cfg, tree)
    motion = simulate(cfg, tree, leaves)
    nodes3d = node_positions(tree, motion)
    times = frame_times(cfg)
    par, child, r0, r1 = _segments(tree)
    rng = _rng(cfg, _S_BARK)
    base, dark, light = _bark_colors(cfg, tree, child, rng)
    if cfg.light == "backlit":
        base, dark, light = ([tuple(BACKLIT_GAIN * v for v in c) for c in cols] for cols in (base, dark, light))
    marks = _bark_marks(cfg, tree, par, child, r0, r1, base, rng)
    return Scene(cfg=cfg, tree=tree, leaves=leaves, motion=motion, nodes3d=nodes3d,
                 background=render_background(cfg), occluder=build_occluder(cfg),
                 cx=cfg.width / 2.0, ground_v=cfg.ground_frac * cfg.height,
                 seg_parent=par, seg_child=child, seg_r0=r0, seg_r1=r1, seg_color=base,
                 seg_dark=dark, seg_light=light, marks=marks,
                 layers=_draw_plan(tree, leaves, par, child, r0, r1, marks), times=times,
                 light=build_light(cfg, times), foreground=build_foreground(cfg, tree, times))


def _validate(cfg: SynthConfig) -> None:
    if cfg.width < 64 or cfg.height < 64 or cfg.frames < 1 or cfg.fps <= 0:
        raise ValueError("need width, height >= 64, frames >= 1, fps > 0")
    if cfg.bark not in ("brown", "grey"):
        raise ValueError("bark must be 'brown' or 'grey'")
    if cfg.kind not in ("deciduous", "conifer", "palm"):
        raise ValueError("kind must be 'deciduous', 'conifer' or 'palm'")
    for name, ok in (("sky", ("blue", "overcast")), ("light", ("sun", "backlit")), ("palette", ("green", "autumn"))):
        if getattr(cfg, name) not in ok:
            raise ValueError(f"{name} must be one of {ok}")
    if cfg.encoder not in ("mp4v", "h264"):
        raise ValueError("encoder must be 'mp4v' or 'h264'")
    if cfg.vfr_header_fps > 0 and cfg.encoder != "h264":
        raise ValueError("a variable frame rate (vfr_header_fps > 0) is written by ffmpeg: set encoder='h264'")


# ----------------------------------------------------------------------------------------------
# per-frame geometry and drawing
# ----------------------------------------------------------------------------------------------
def leaf_centres(scene: Scene, f: int) -> np.ndarray:
    """Leaf centres of frame f (Lv, 2) frame-1 pixels, incl. flutter."""
    lv = scene.leaves
    A = scene.motion.A[:, f][lv.branch]
    t = scene.motion.t[:, f][lv.branch]
    world = np.einsum("lij,lj->li", A, lv.rest) + t
    tsec = scene.times[f] if scene.times is not None else f / scene.cfg.fps
    flutter = lv.flutter_amp * np.sin(2 * np.pi * lv.flutter_freq * tsec + lv.flutter_phase)
    return project(scene, world) + flutter


def _turn_angle(scene: Scene, f: int) -> np.ndarray:
    """Turning angle of every leaf card at frame f (Lv,) rad (turning leaves only)."""
    lv = scene.leaves
    return lv.turn_amp * np.sin(2 * np.pi * lv.turn_freq * scene.times[f] + lv.turn_phase)


def leaf_polygons(scene: Scene, f: int) -> np.ndarray:
    """Leaf polygons of frame f (Lv, 6, 2) frame-1 px. A palm's leaflet turns and foreshortens with
    its frond segment; a turning card (``leaf_turn_deg``) turns in the image plane about its
    petiole (vertex 3) by its angle and its width foreshortens by cos(tilt + angle) / cos(tilt)."""
    lv = scene.leaves
    if lv.turn_amp is None and lv.axis is None:
        return leaf_centres(scene, f)[:, None, :] + lv.shape
    shape = lv.shape
    if lv.axis is not None:
        A = scene.motion.A[:, f][lv.branch]
        d = np.einsum("lij,lj->li", A, lv.axis)
        p_now = np.stack([d[:, 0], -d[:, 2]], 1)
        p_rest = np.stack([lv.axis[:, 0], -lv.axis[:, 2]], 1)
        ang = np.arctan2(p_now[:, 1], p_now[:, 0]) - np.arctan2(p_rest[:, 1], p_rest[:, 0])
        ratio = np.clip(np.maximum(np.linalg.norm(p_now, axis=1), 0.15)
                        / np.maximum(np.linalg.norm(p_rest, axis=1), 0.15), 0.25, 4.0)
        u = _unit(shape[:, 0] - shape[:, 3])
        v = np.stack([-u[:, 1], u[:, 0]], 1)
        a_c = np.einsum("lkc,lc->lk", shape, u) * ratio[:, None]
        b_c = np.einsum("lkc,lc->lk", shape, v)
        shape = _rotate2d(a_c[..., None] * u[:, None] + b_c[..., None] * v[:, None], ang)
    if lv.turn_amp is not None:
        alpha = _turn_angle(scene, f)
        pivot = shape[:, 3:4]
        rel = shape - pivot
        u = _unit(shape[:, 0] - shape[:, 3])
        v = np.stack([-u[:, 1], u[:, 0]], 1)
        fs = np.cos(lv.tilt + alpha) / np.cos(lv.tilt)
        a_c = np.einsum("lkc,lc->lk", rel, u)
        b_c = np.einsum("lkc,lc->lk", rel, v) * fs[:, None]
        shape = pivot + _rotate2d(a_c[..., None] * u[:, None] + b_c[..., None] * v[:, None], alpha)
    return leaf_centres(scene, f)[:, None, :] + shape


def _rotate2d(p: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """Rotate (L, K, 2) points by (L,) rad (image x right, y down: positive turns x toward y)."""
    c, s_ = np.cos(ang)[:, None], np.sin(ang)[:, None]
    return np.stack([c * p[..., 0] - s_ * p[..., 1], s_ * p[..., 0] + c * p[..., 1]], -1)


def leaf_colors(scene: Scene, f: int) -> list:
    """BGR colour of every leaf at frame f: a turning card gets brighter or darker as it turns
    toward or away from the light (x (1 + 0.8 (sin(tilt + angle) - sin(tilt))))."""
    lv = scene.leaves
    if lv.turn_amp is None:
        return lv.color
    g = 1.0 + 0.8 * (np.sin(lv.tilt + _turn_angle(scene, f)) - np.sin(lv.tilt))
    col = np.clip(np.asarray(lv.color) * g[:, None], 0, 255)
    return [tuple(float(v) for v in c) for c in col]


def _frame_geometry(scene: Scene, f: int) -> dict:
    """Polygons of frame f in frame-1 pixels, as int32 with _SHIFT fractional bits."""
    P = project(scene, scene.nodes3d[f])
    p0, p1 = P[scene.seg_parent], P[scene.seg_child]
    d = p1 - p0
    ln = np.linalg.norm(d, axis=1)
    d = d / np.maximum(ln, 1e-9)[:, None]
    n = np.stack([-d[:, 1], d[:, 0]], 1)
    n *= np.where(n[:, :1] < 0, -1.0, 1.0)             # normals point right: shadow side
    r0, r1 = scene.seg_r0[:, None], scene.seg_r1[:, None]

    def band(w_a, w_b):
        return np.stack([p0 + n * w_a * r0, p1 + n * w_a * r1, p1 + n * w_b * r1,
                         p0 + n * w_b * r0], 1)

    mk = scene.marks
    ms = mk["seg"]
    r_at = scene.seg_r0[ms] + (scene.seg_r1[ms] - scene.seg_r0[ms]) * mk["s"]
    c = p0[ms] + d[ms] * (mk["s"] * ln[ms])[:, None] + n[ms] * (mk["w"] * r_at)[:, None]
    e1 = np.where(mk["along"][:, None], d[ms], n[ms]) * mk["half_len"][:, None]
    e2 = np.where(mk["along"][:, None], n[ms], d[ms]) * mk["half_wid"][:, None]
    marks = np.stack([c + e1 + e2, c + e1 - e2, c - e1 - e2, c - e1 + e2], 1)
    leaves = leaf_polygons(scene, f)

    def fix(a):
        return np.rint(a * _SUB).astype(np.int32)

    return dict(P=P, Pi=fix(P).tolist(), quad=fix(band(1.0, -1.0)), dark=fix(band(0.3, 1.0)),
                light=fix(band(-0.75, -0.3)), marks=fix(marks), leaves=fix(leaves),
                jr=np.rint(scene.tree.radius * _SUB).astype(int).tolist(), leaf_col=leaf_colors(scene, f))


def _draw_tree(img: np.ndarray, scene: Scene, geo: dict, label: bool) -> None:
    """Painter's algorithm over the depth layers.  label=True draws LABEL_* values without
    anti-aliasing or bark detail into a single-channel image."""
    lt = cv2.LINE_8 if label else cv2.LINE_AA
    Pi, jr, quad, leaves = geo["Pi"], geo["jr"], geo["quad"], geo["leaves"]
    par, child = scene.seg_parent, scene.seg_child
    seg_col = scene.seg_color
    leaf_col = geo["leaf_col"]
    bc, lc = (LABEL_BRANCH,), (LABEL_LEAF,)
    for layer in scene.layers:
        for i in layer["thin"]:
            cv2.line(img, tuple(Pi[par[i]]), tuple(Pi[child[i]]), bc if label else seg_col[i], 1,
                     lt, _SHIFT)
        for i in layer["joints"]:
            c = child[i]
            cv2.circle(img, tuple(Pi[c]), jr[c], bc if label else seg_col[i], -1, lt, _SHIFT)
        for i in layer["thick"]:
            cv2.fillConvexPoly(img, quad[i], bc if label else seg_col[i], lt, _SHIFT)
        if not label:
            dark, light, marks = geo["dark"], geo["light"], geo["marks"]
            for i in layer["shaded"]:
                cv2.fillConvexPoly(img, dark[i], scene.seg_dark[i], lt, _SHIFT)
                cv2.fillConvexPoly(img, light[i], scene.seg_light[i], lt, _SHIFT)
            mcol = scene.marks["color"]
            for i in layer["marks"]:
                cv2.fillConvexPoly(img, marks[i], mcol[i], lt, _SHIFT)
        for i in layer["leaves"]:
            cv2.fillConvexPoly(img, leaves[i], lc if label else leaf_col[i], lt, _SHIFT)


def render_clean(scene: Scene, f: int) -> np.ndarray:
    """Frame f (H, W, 3) uint8 BGR in frame-1 camera coordinates, before camera motion/noise."""
    img = scene.background.copy()
    _draw_tree(img, scene, _frame_geometry(scene, f), label=False)
    _paste_occluder(img, scene.occluder, f)
    if scene.foreground is not None:
        _paste_foreground(img, scene, f)
    return img


def render_frame(scene: Scene, f: int) -> np.ndarray:
    """Final frame f (H, W, 3) uint8 BGR as written to the video (camera motion, noise, JPEG)."""
    cfg = scene.cfg
    img = render_clean(scene, f)
    if scene.light is not None:
        img = np.clip(img.astype(np.float32) * light_multiplier(scene, f)[..., None] + np.float32(0.5),
                      0, 255).astype(np.uint8)
    dx, dy = scene.motion.camera_offset[f]
    if dx != 0 or dy != 0:
        M = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
        img = cv2.warpAffine(img, M, (cfg.width, cfg.height), flags=cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_REFLECT101)
    if cfg.noise_sigma > 0:
        rng = _rng(cfg, _S_NOISE, f)
        noise = rng.standard_normal(img.shape, dtype=np.float32) * np.float32(cfg.noise_sigma)
        img = np.clip(img.astype(np.float32) + noise + np.float32(0.5), 0, 255).astype(np.uint8)
    if cfg.jpeg_quality > 0:
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(cfg.jpeg_quality)])
        img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return img


def render_labels(scene: Scene, f: int, foreground: bool = True) -> np.ndarray:
    """Label image (H, W) uint8 of frame f in frame-1 coordinates: LABEL_BACKGROUND/BRANCH/LEAF/
    OCCLUDER/FOREGROUND (depth-ordered like the colour rendering; ``foreground=False``: the tree
    and the occluder only)."""
    lab = np.zeros((scene.cfg.height, scene.cfg.width), np.uint8)
    _draw_tree(lab, scene, _frame_geometry(scene, f), label=True)
    _paste_occluder(lab, scene.occluder, f, value=LABEL_OCCLUDER)
    if foreground and scene.foreground is not None:
        layer = _foreground_layer(scene.cfg, scene.foreground, f)
        if layer is not None:
            _, a, (x0, y0) = layer
            region = lab[y0:y0 + a.shape[0], x0:x0 + a.shape[1]]
            region[a >= FOREGROUND_ALPHA] = LABEL_FOREGROUND
    return lab


# ----------------------------------------------------------------------------------------------
# outline (user-like polygon)
# ----------------------------------------------------------------------------------------------
def _contains(poly: np.ndarray, sil: np.ndarray) -> bool:
    m = np.zeros(sil.shape, np.uint8)
    cv2.fillPoly(m, [np.rint(poly).astype(np.int32)], 1)
    return bool(np.all(m[sil] > 0))


def _simplify(contour: np.ndarray, lo: int = 24, hi: int = 44) -> np.ndarray:
    """approxPolyDP with an epsilon chosen to give lo..hi vertices (K, 2) float."""
    a, b = 0.5, 60.0
    best = None
    for _ in range(30):
        eps = 0.5 * (a + b)
        ap = cv2.approxPolyDP(contour, eps, True).reshape(-1, 2)
        if len(ap) > hi:
            a = eps
        elif len(ap) < lo:
            b = eps
        else:
            best = ap
            break
        best = ap
    if not 20 <= len(best) <= 60:                       # fall back to evenly spaced contour points
        pts = contour.reshape(-1, 2)
        best = pts[np.linspace(0, len(pts), 32, endpoint=False).astype(int)]
    return best.astype(float)


def outline_polygon(cfg: SynthConfig, silhouette: np.ndarray) -> np.ndarray:
    """Loose hand-drawn-like polygon (K, 2) px, 20-60 vertices, a few px outside ``silhouette``
    (H, W) bool (tree pixels of frame 1)."""
    rng = _rng(cfg, _S_OUTLINE)
    s = _scale(cfg)
    h, w = silhouette.shape
    sil8 = silhouette.astype(np.uint8)
    kk = 2 * int(math.ceil(2 * s)) + 1                  # keep >= ~2 px clearance
    clear = cv2.dilate(sil8, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (kk, kk))) > 0
    poly = None
    for attempt in range(8):
        margin = (4.0 + 2.0 * attempt) * s
        k = 2 * int(math.ceil(margin)) + 1
        dil = cv2.dilate(sil8, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
        kc = 2 * int(0.045 * h * (1 + 0.5 * attempt)) + 1
        closed = cv2.morphologyEx(dil, cv2.MORPH_CLOSE,
                                  cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (kc, kc)))
        closed = cv2.copyMakeBorder(closed, kc, kc, kc, kc, cv2.BORDER_CONSTANT, 0)[kc:-kc, kc:-kc]
        cnts, _ = cv2.findContours(closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        if not cnts:
            break
        big = max(cnts, key=cv2.contourArea)
        cand = _simplify(big)
        if _contains(cand, clear):
            poly = cand
            break
    if poly is None:                                    # fall back to a convex hull
        pts = np.argwhere(silhouette)[:, ::-1].astype(np.float32)
        hull = cv2.convexHull(pts).reshape(-1, 2)
        cen = hull.mean(axis=0)
        poly = cen + (hull - cen) * 1.05 + _unit(hull - cen) * 5 * s
    cen = poly.mean(axis=0)
    jittered = poly + _unit(poly - cen) * rng.uniform(0.0, 2.0, (len(poly), 1)) * s
    if _contains(jittered, clear):
        poly = jittered
    poly[:, 0] = np.clip(poly[:, 0], 0, w - 1)
    poly[:, 1] = np.clip(poly[:, 1], 0, h - 1)
    return np.round(poly, 1)


# ----------------------------------------------------------------------------------------------
# generation
# ----------------------------------------------------------------------------------------------
def _visibility(scene: Scene, max_samples: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """Share of sampled frames in which each node's pixel shows branch (not leaves/occluder),
    (N,) float32; and the frame-0 label image (H, W) uint8."""
    cfg = scene.cfg
    stride = max(1, int(math.ceil(cfg.frames / max_samples)))
    frames = list(range(0, cfg.frames, stride))
    vis = np.zeros(len(scene.tree.rest))
    lab0 = None
    for f in frames:
        lab = render_labels(scene, f)
        if lab0 is None:
            lab0 = lab
        uv = np.rint(project(scene, scene.nodes3d[f])).astype(int)
        u = np.clip(uv[:, 0], 0, cfg.width - 1)
        v = np.clip(uv[:, 1], 0, cfg.height - 1)
        vis += lab[v, u] == LABEL_BRANCH
    return (vis / len(frames)).astype(np.float32), lab0


def _height_px(scene: Scene) -> float:
    """Root-to-top height of the frame-1 tree incl. leaves (px)."""
    P = project(scene, scene.nodes3d[0])
    top_nodes = (P[:, 1] - scene.tree.radius).min()
    leaves = leaf_polygons(scene, 0)
    top = min(top_nodes, leaves[..., 1].min()) if len(leaves) else top_nodes
    return float(scene.ground_v - top)


def truth_arrays(scene: Scene, visible_frac: np.ndarray | None = None) -> dict:
    """Ground-truth arrays (see module docstring / generate) for scene."""
    cfg = scene.cfg
    nodes3d = scene.nodes3d.astype(np.float32)
    nodes2d = project(scene, scene.nodes3d).astype(np.float32)
    off = scene.motion.camera_offset.astype(np.float32)
    lc = leaf_centres(scene, 0)
    ncl = len(scene.leaves.cluster_dark)
    cnt = np.maximum(np.bincount(scene.leaves.cluster, minlength=ncl), 1)
    leaf_pos = np.stack([np.bincount(scene.leaves.cluster, lc[:, k], ncl) / cnt for k in (0, 1)], 1)
    if visible_frac is None:
        visible_frac = np.full(len(scene.tree.rest), np.nan, np.float32)
    out = {
        "parents": scene.tree.parents.astype(np.int32),
        "nodes3d": nodes3d,
        "nodes2d": nodes2d,
        "nodes2d_image": (nodes2d + off[:, None, :]).astype(np.float32),
        "camera_offset": off,
        "radius": scene.tree.radius.astype(np.float32),
        "freq": scene.motion.branch_freq[scene.tree.node_branch].astype(np.float32),
        "depth_level": scene.tree.depth_level.astype(np.int32),
        "branch_id": scene.tree.node_branch.astype(np.int32),
        "fps": np.float64(cfg.fps),
        "height_px": np.float32(_height_px(scene)),
        "visible_frac": visible_frac.astype(np.float32),
        "occluder_boxes": occluder_boxes(cfg, scene.occluder, scene.motion.camera_offset),
        "leaf_pos2d": leaf_pos.astype(np.float32),
        "leaf_dark": scene.leaves.cluster_dark.astype(bool),
        "variant": np.array(cfg.variant),
        "bark": np.array(cfg.bark),
        "width": np.int32(cfg.width),
        "height": np.int32(cfg.height),
        "cx": np.float32(scene.cx),
        "ground_v": np.float32(scene.ground_v),
        "seed": np.int64(cfg.seed),
    }
    out.update(_wind_truth(scene))
    return out


def _wind_truth(scene: Scene) -> dict:
    """Truth of the wind and light options (only the keys of the options that are on, and times)."""
    cfg, lv, mo = scene.cfg, scene.leaves, scene.motion
    times = scene.times
    out: dict = {"times": times.astype(np.float64)}
    if cfg.vfr_header_fps > 0:
        out["fps"] = np.float64((len(times) - 1) / times[-1]) if len(times) > 1 else np.float64(cfg.fps)
        out["header_fps"] = np.float64(cfg.vfr_header_fps)
    if lv.turn_amp is not None:
        out["leaf_turn_deg"] = np.degrees(lv.turn_amp).astype(np.float32)
        out["leaf_turn_hz"] = lv.turn_freq.astype(np.float32)
    if mo.swing_deg is not None:
        out["swing_deg"] = mo.swing_deg.astype(np.float32)
    if mo.lean is not None:
        out["lean"] = mo.lean.astype(np.float32)
        out["gust_onset"] = mo.gusts["onset"].astype(np.float32)
        out["gust_rise"] = mo.gusts["rise"].astype(np.float32)
        out["gust_lean"] = mo.gusts["peak"].astype(np.float32)
    if scene.light is not None:
        out["light_gain"] = scene.light.gain.astype(np.float32)
        if scene.light.shadow is not None:
            out["shadow_velocity"] = scene.light.velocity.astype(np.float32)
            out["shadow_depth"] = np.float32(scene.light.depth)
    if scene.foreground is not None:
        out["foreground_mask"] = np.stack([foreground_mask(scene, f) for f in range(cfg.frames)])
    if scene.tree.part is not None:
        out["node_part"] = scene.tree.part.astype(np.int8)
        out["frond_id"] = scene.tree.frond.astype(np.int32)
        out["frond_count"] = np.int32(len(scene.tree.frond_branches))
    return out


def _ffmpeg() -> str:
    exe = shutil.which("ffmpeg")
    if exe is None:
        raise RuntimeError("ffmpeg is not installed; it writes the H.264 and variable-frame-rate samples "
                           "(Debian: apt-get install -y ffmpeg)")
    return exe


_X264 = ["-c:v", "libx264", "-preset", "veryfast", "-crf", "18", "-pix_fmt", "yuv420p"]


def _write_h264(scene: Scene, path: Path, progress: Callable[[int, int], None] | None) -> None:
    """Frames piped as raw BGR into the ffmpeg CLI, H.264 (libx264, yuv420p) in an MP4 at cfg.fps."""
    cfg = scene.cfg
    cmd = [_ffmpeg(), "-v", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24", "-s", f"{cfg.width}x{cfg.height}",
           "-framerate", repr(float(cfg.fps)), "-i", "-", *_X264, "-movflags", "+faststart", str(path)]
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=err)
        assert proc.stdin is not None
        try:
            for f in range(cfg.frames):
                proc.stdin.write(render_frame(scene, f).tobytes())
                if progress is not None:
                    progress(f + 1, cfg.frames)
        except BrokenPipeError:
            pass
        finally:
            proc.stdin.close()
            rc = proc.wait()
        if rc != 0:
            err.seek(0)
            raise RuntimeError(f"ffmpeg could not write {path} (exit {rc}): {err.read().decode(errors='replace')[-400:]}")


def _write_vfr(scene: Scene, path: Path, progress: Callable[[int, int], None] | None) -> None:
    """Frames at their own times (scene.times, whole ms) into an MKV, H.264, whose header declares
    ``vfr_header_fps``: PNG frames in a temporary folder, an ffconcat list with each frame's
    duration, ffmpeg with pass-through timestamps and a 1 ms time base."""
    cfg = scene.cfg
    ms = np.rint(scene.times * 1000.0).astype(np.int64)
    tmp = tempfile.mkdtemp(prefix=".frames_", dir=path.parent)
    try:
        lines = ["ffconcat version 1.0"]
        for f in range(cfg.frames):
            name = f"{f:06d}.png"
            cv2.imwrite(os.path.join(tmp, name), render_frame(scene, f))
            dur = ms[f + 1] - ms[f] if f + 1 < cfg.frames else max(int(round(1000.0 / cfg.fps)), 1)
            lines += [f"file {name}", "option framerate 1000", f"duration {dur / 1000.0:.3f}"]
            if progress is not None:
                progress(f + 1, cfg.frames)
        listing = os.path.join(tmp, "frames.ffconcat")
        Path(listing).write_text("\n".join(lines) + "\n")
        cmd = [_ffmpeg(), "-v", "error", "-y", "-f", "concat", "-safe", "0", "-i", listing, "-vsync", "passthrough",
               "-enc_time_base", "1:1000", "-r", repr(float(cfg.vfr_header_fps)), *_X264, str(path)]
        done = subprocess.run(cmd, capture_output=True)
        if done.returncode != 0:
            raise RuntimeError(f"ffmpeg could not write {path} (exit {done.returncode}): "
                               f"{done.stderr.decode(errors='replace')[-400:]}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def generate(cfg: SynthConfig, out_dir: str | os.PathLike,
             progress: Callable[[int, int], None] | None = None) -> dict:
    """Render ``cfg`` into ``out_dir``; returns {"video", "outline", "mask", "truth"} paths (str).

    Files: video.mp4 ('mp4v', or H.264 with ``encoder="h264"``; cfg.fps, width x height, cfg.frames
    frames; video.mkv for a variable frame rate, see ``vfr_header_fps``); outline.json
    {"polygon": [[x, y], ...]} frame-1 px; mask.png uint8 0/255 filled polygon (H, W);
    truth.npz (np.savez_compressed, no object arrays) with
      parents (N,) int32 (-1 root), nodes3d (F, N, 3) float32 world px (x right, y depth, z up),
      nodes2d (F, N, 2) float32 frame-1 camera px, nodes2d_image (F, N, 2) float32 image px
      (= nodes2d + camera_offset), camera_offset (F, 2) float32 px, radius (N,) float32 px,
      freq (N,) float32 Hz, depth_level (N,) int32, branch_id (N,) int32, fps float64,
      height_px float32, visible_frac (N,) float32 (share of sampled frames whose node pixel
      shows branch), occluder_boxes (F, 4) float32 image px (-1 when none), leaf_pos2d (L, 2)
      float32 frame-1 px of leaf cluster centres, leaf_dark (L,) bool, variant / bark 0-d str,
      width, height int32, cx, ground_v float32 (u = cx + x, v = ground_v - z), seed int64,
      times (F,) float64 s; and the keys of the wind options that are on (sample_videos/README.md).
    ``progress(done_frames, total_frames)`` is called after every written frame.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene = build_scene(cfg)
    paths = {"video": out / ("video.mkv" if cfg.vfr_header_fps > 0 else "video.mp4"),
             "outline": out / "outline.json", "mask": out / "mask.png", "truth": out / "truth.npz"}
    if cfg.vfr_header_fps > 0:
        _write_vfr(scene, paths["video"], progress)
    elif cfg.encoder == "h264":
        _write_h264(scene, paths["video"], progress)
    else:
        writer = cv2.VideoWriter(str(paths["video"]), cv2.VideoWriter_fourcc(*"mp4v"), float(cfg.fps),
                                 (cfg.width, cfg.height))
        if not writer.isOpened():
            raise RuntimeError(f"cv2.VideoWriter could not open {paths['video']}")
        try:
            for f in range(cfg.frames):
                writer.write(render_frame(scene, f))
                if progress is not None:
                    progress(f + 1, cfg.frames)
        finally:
            writer.release()
    vis, lab0 = _visibility(scene)
    if scene.foreground is not None:                    # the user outlines the tree, not the branch in front
        lab0 = render_labels(scene, 0, foreground=False)
    poly = outline_polygon(cfg, (lab0 == LABEL_BRANCH) | (lab0 == LABEL_LEAF))
    paths["outline"].write_text(json.dumps({"polygon": poly.tolist()}))
    mask = np.zeros((cfg.height, cfg.width), np.uint8)
    cv2.fillPoly(mask, [np.rint(poly).astype(np.int32)], 255)
    cv2.imwrite(str(paths["mask"]), mask)
    np.savez_compressed(paths["truth"], **truth_arrays(scene, vis))
    return {k: str(v) for k, v in paths.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Synthetic swaying-tree video with ground truth.")
    ap.add_argument("--variant", default="broad", choices=VARIANTS + ("all",),
                    help="preset; 'all' writes every variant into OUT/<variant>/")
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--width", type=int)
    ap.add_argument("--height", type=int)
    ap.add_argument("--frames", type=int)
    ap.add_argument("--fps", type=float)
    ap.add_argument("--seed", type=int)
    a = ap.parse_args(argv)
    names = VARIANTS if a.variant == "all" else (a.variant,)
    for name in names:
        cfg = config_for(name, width=a.width, height=a.height, frames=a.frames, fps=a.fps,
                         seed=a.seed)
        out = Path(a.out) / name if a.variant == "all" else Path(a.out)
        t0 = time.perf_counter()
        paths = generate(cfg, out)
        print(json.dumps({"variant": name, "seconds": round(time.perf_counter() - t0, 2), **paths}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
