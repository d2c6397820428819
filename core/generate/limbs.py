"""Limbs grown where the video shows none (issue 19, item 5).

A crown so dense that no bark shows between its leaves gives the trace nothing to follow; the
reconstruction then links the motion hierarchy's clusters with straight lines, a web that reads as
no tree. Here the crown above the reconstruction's own trunk is grown instead, by space
colonization (:mod:`.colonize`) toward points spread over frame 1's tree pixels (image pixels as
units, x right and z up from the trunk base), driven by a species: its bone length is the step,
its mean branch angle from the vertical sets the upward pull, its shortest branch the stubs
pruned. (The generator's pair growth, :func:`.growth.grow_2d`, was tried here first: in a crown's
picture plane it tangles and hooks.) The species is a library one of the tree's form or one the
user fitted. The grown nodes then move with the tracks near them, as traced nodes do
(:func:`..reconstruct.node_motion.follow_tracks`).

Kept from the reconstruction: the trunk (node 0 to the first fork, at most :data:`TRUNK_MAX` of
the height; rising on straight to where the crown widens, as a generated tree's) and a hidden
trunk's flag. Palms are never grown here: their crown is fronds.
"""
from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from ..errors import InputError
from ..outline import largest_component
from ..reconstruct.node_motion import follow_tracks
from ..reconstruct.run import Result
from ..reconstruct.skeleton2d import NODE_MOTION_SCALE, Skeleton2D, binarize, crown_scale
from ..topology import branching_level, trunk_chain
from .colonize import colonize, prune_stubs
from .envelopes import Region2D
from .growth import stem_top
from .species import SpeciesModel

#: where the crown's limbs come from: ``auto`` grown when no bark is visible in the crown (the
#: trace found none), ``trace`` always traced, ``grow`` always grown
LIMB_SOURCES = ("auto", "trace", "grow")
#: the library species grown in a crown of each form when none is given
SPECIES_OF_FORM = {"broadleaf": "broad", "conifer": "conifer"}
#: the tree's pixels are closed over gaps this share of the height wide (sky between leaves)
CLOSE_FRAC = 0.03
#: a kept trunk ends at most this share of the height above the base
TRUNK_MAX = 0.6
#: node budget of the grown tree: the reconstruction's node count, within these bounds
BUDGET = (100, 400)
#: the growth step (one bone) is the species' bone length, within these shares of the height
STEP_FRAC = (0.02, 0.04)
#: attraction points spread over the crown; a point pulls nodes within this share of the
#: height and is taken by one within this many steps
ATTRACTORS = 1500
INFLUENCE_FRAC = 0.12
KILL_STEPS = 1.5
#: upward pull w_up at a species whose branches stand vertical (× cos of its mean angle from it)
UP_PULL = 0.3
#: crown points from this share of the height below the trunk's top
FOOT_FRAC = 0.05


def limb_species(spec: str, form: str) -> SpeciesModel:
    """The species grown in a crown of ``form``: ``spec`` (a library name or a species .json file)
    or, when empty, the library's species of that form (:data:`SPECIES_OF_FORM`)."""
    from .batch import load_species_spec
    from .species import species_library
    if spec:
        return load_species_spec(spec)[0]
    name = SPECIES_OF_FORM.get(form, "broad")
    lib = species_library()
    if name not in lib:
        raise InputError(f"no species '{name}' in the library to grow a {form}'s limbs; give one with "
                         "--limb-species FILE.json or trace them (--limbs trace)")
    return load_species_spec(name)[0]


def _height_px(mask: np.ndarray, base: np.ndarray) -> float:
    """Height (px) of frame 1's tree pixels ``mask (H, W)`` bool down to the trunk base
    ``base (2,)`` (x, y) px."""
    rows = np.flatnonzero(np.asarray(mask, bool).any(1))
    if len(rows) == 0:
        raise InputError("frame 1 shows no tree pixels to grow limbs in; trace them (--limbs trace)")
    return float(max(base[1], rows.max()) - rows.min() + 1)


def crown_region(mask: np.ndarray, trunk_px: np.ndarray, height: float) -> Region2D:
    """Ω' from frame 1's tree pixels ``mask (H, W)`` bool and the kept trunk ``trunk_px (K, 2)``
    (x, y) px from its base: the largest part of the pixels closed over gaps of
    :data:`CLOSE_FRAC` of the tree's ``height`` (px; the crown), the trunk drawn in and joined to
    the crown by a straight stem from its top, as (x − x_base, y_base − y) px."""
    base = trunk_px[0]
    k = max(3, int(round(CLOSE_FRAC * height)) | 1)
    closed = cv2.morphologyEx(np.asarray(mask, np.uint8), cv2.MORPH_CLOSE,
                              cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    crown = largest_component(closed > 0).astype(np.uint8)
    ys, xs = np.nonzero(crown)
    top = trunk_px[-1]
    near = int(np.argmin((xs - top[0]) ** 2 + (ys - top[1]) ** 2))
    line = np.vstack([trunk_px, [[xs[near], ys[near]]]])
    cv2.polylines(crown, [np.round(line).astype(np.int32).reshape(-1, 1, 2)], False, 1, max(3, k // 2))
    contours, _ = cv2.findContours(crown, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    c = max(contours, key=cv2.contourArea).reshape(-1, 2).astype(np.float64)
    poly = np.stack([c[:, 0] - base[0], base[1] - c[:, 1]], 1)
    return Region2D(poly)


def grown_limbs(res: Result, model: SpeciesModel, seed: int = 0, budget: int | None = None) -> Skeleton2D:
    """``res.skeleton`` with its crown regrown from ``model`` in frame 1's tree pixels (module
    docstring); ``budget`` nodes (None: the reconstruction's count within :data:`BUDGET`).
    Deterministic per ``seed``."""
    sk = res.skeleton
    mask = res.foreground.mask if res.foreground is not None else res.outline.mask
    p0 = sk.nodes2d[0].astype(np.float64)
    base = p0[0]
    height = _height_px(mask, base)
    chain = trunk_chain(sk.parents)
    trunk = np.stack([p0[chain, 0] - base[0], base[1] - p0[chain, 1]], 1)
    low = trunk[:, 1] <= TRUNK_MAX * height
    trunk = trunk[:max(2, int(np.argmin(low)) if not low.all() else len(trunk))]
    if len(trunk) < 2 or np.linalg.norm(trunk[-1] - trunk[0]) < 1e-6:
        trunk = np.array([[0.0, 0.0], [0.0, 0.3 * height]])
    region = crown_region(mask, np.stack([base[0] + trunk[:, 0], base[1] - trunk[:, 1]], 1), height)
    # a fork below where the crown widens would have no room: the trunk rises on to there, as a
    # generated tree's does (:func:`.growth.stem_top`)
    up = min(stem_top(region) + 0.02 * height, TRUNK_MAX * height)
    if trunk[-1, 1] < up and region.contains(np.array([[trunk[-1, 0], up]]))[0]:
        trunk = np.vstack([trunk, [trunk[-1, 0], up]])
    step = float(np.clip(model.segment_frac, *STEP_FRAC)) * height
    conifer = res.form == "conifer"
    growing = np.zeros(len(trunk), bool)
    growing[-1] = True
    if conifer:                       # a leader to the top, every node of it above the crown's foot sprouting
        top = float(region.height())
        z = np.arange(trunk[-1, 1] + step, 0.97 * top, step)
        leader = np.stack([np.full(len(z), trunk[-1, 0]), z], 1)
        leader = leader[region.contains(leader)]
        growing = np.concatenate([growing, np.ones(len(leader), bool)])
        trunk = np.vstack([trunk, leader])
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x11B5])
    cells = np.stack(np.nonzero(region.mask)[::-1], 1).astype(np.float64)
    xz = np.stack([region.x0 + cells[:, 0] * region.cell, region.z_top - cells[:, 1] * region.cell], 1)
    xz = xz[xz[:, 1] >= trunk[np.argmax(growing), 1] - FOOT_FRAC * height]      # the crown, not the trunk's foot
    pts = xz[rng.choice(len(xz), min(ATTRACTORS, len(xz)), replace=False)] if len(xz) else xz
    pts = pts + rng.uniform(-0.5, 0.5, pts.shape) * region.cell
    n = int(np.clip(sk.n_nodes if budget is None else budget, *BUDGET))
    o_mean = float(model.orientation_deg[0])
    c = colonize(np.arange(len(trunk)) - 1, trunk, growing, pts, step, INFLUENCE_FRAC * height, KILL_STEPS * step,
                 up=UP_PULL * float(np.cos(np.radians(o_mean))), budget=n, inside=region.contains)
    par, xz = prune_stubs(c.parents, c.pos, max(float(model.min_branch_frac) * height, 1.5 * step))
    pos = np.stack([base[0] + xz[:, 0], base[1] - xz[:, 1]], 1)
    parents, pos = binarize(par, pos)
    fixed = np.zeros(len(parents), bool)
    fixed[0] = True
    mo = follow_tracks(pos, res.tracks, NODE_MOTION_SCALE * crown_scale(res.outline), fixed)
    note = (f"the crown's limbs are grown from the species '{model.name}' inside frame 1's tree pixels "
            f"({len(parents)} nodes, {c.left} of {len(pts)} crown points unreached): the video does not show them")
    return replace(sk, parents=parents.astype(np.int32), nodes2d=mo.nodes, level=branching_level(parents).astype(np.int32),
                   kind="grown", warnings=[*sk.warnings, note], confidence=mo.confidence)
