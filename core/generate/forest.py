"""Forest placement: where N generated trees stand, and how each differs (pure numpy, no bpy).

* :func:`scatter_area` — Poisson-disk points in a ``width × depth`` rectangle (Bridson 2007:
  an active list, ``k = 30`` candidates per point in the annulus [r, 2r], a background grid of
  cell ``r/√2`` so each test looks at 5×5 cells), then ``n`` of them chosen at random.
* :func:`scatter_on_mesh` — points on triangles ``(T, 3, 3)``: area-weighted candidates
  (triangle by area, then uniform barycentric ``(1 − √u, √u (1 − v), √u v)``), accepted in random
  order when at least ``min_dist`` from every accepted one (dart throwing on a hash grid).
* :func:`forest_slots` — per tree a distinct seed, a rotation about z, a time offset and a tree
  phase so neighbours do not sway in lockstep, and a small size jitter; with ``variants`` V > 0
  the trees are V variants, each standing several times (turned, sized and out of step), as a
  forest of SpeedTree models is: the .blend keeps each variant's mesh and motion once.
* :func:`generate_forest` — the trees themselves (:func:`.growth.grow_tree`), one per variant,
  with progress and cancel like reconstruction; a shared variant sways in a loop of the forest's
  length (:func:`instance_offsets`: each of its trees plays it from its own frame).

When ``n`` trees do not fit at ``min_dist`` an :class:`InputError` names how many fit (or, with
``strict=False``, the points that fit are returned and a warning is issued).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError
from ..params import param
from ..progress import ProgressFn, report, sub_progress


def _too_few(n: int, got: int, where: str, min_dist: float, strict: bool) -> None:
    msg = (f"only {got} of {n} trees fit {where} {min_dist:g} m apart; lower the spacing, "
           f"enlarge the area or ask for at most {got} trees")
    if strict:
        raise InputError(msg)
    warnings.warn(msg, RuntimeWarning, stacklevel=3)


def poisson_disk(width: float, depth: float, r: float, rng: np.random.Generator, k: int = 30,
                 limit: int | None = None) -> np.ndarray:
    """Bridson's maximal Poisson-disk set ``(M, 2)`` in ``[0, width) × [0, depth)``, every pair at
    least ``r`` apart (stops early at ``limit`` points)."""
    cell = r / math.sqrt(2.0)
    gw, gd = max(1, int(math.ceil(width / cell))), max(1, int(math.ceil(depth / cell)))
    grid = np.full((gw, gd), -1, np.int64)
    pts = [rng.uniform([0.0, 0.0], [width, depth])]
    grid[int(pts[0][0] / cell), int(pts[0][1] / cell)] = 0
    active = [0]
    off = np.array([(i, j) for i in range(-2, 3) for j in range(-2, 3)])
    while active and (limit is None or len(pts) < limit):
        a = int(rng.integers(len(active)))
        p = pts[active[a]]
        rad = r * np.sqrt(rng.uniform(1.0, 4.0, k))                  # uniform area in [r, 2r]
        ang = rng.uniform(0.0, 2 * np.pi, k)
        cand = p + np.stack([rad * np.cos(ang), rad * np.sin(ang)], 1)
        inside = (cand[:, 0] >= 0) & (cand[:, 0] < width) & (cand[:, 1] >= 0) & (cand[:, 1] < depth)
        placed = False
        P = np.asarray(pts)
        for c in cand[inside]:
            gi, gj = int(c[0] / cell), int(c[1] / cell)
            nb = off + [gi, gj]
            nb = nb[(nb[:, 0] >= 0) & (nb[:, 0] < gw) & (nb[:, 1] >= 0) & (nb[:, 1] < gd)]
            idx = grid[nb[:, 0], nb[:, 1]]
            idx = idx[idx >= 0]
            if len(idx) and np.min(np.sum((P[idx] - c) ** 2, 1)) < r * r:
                continue
            pts.append(c)
            grid[gi, gj] = len(pts) - 1
            active.append(len(pts) - 1)
            placed = True
            break
        if not placed:
            active.pop(a)
    return np.asarray(pts)


def scatter_area(n: int, width_m: float, depth_m: float, min_dist: float, seed: int = 0,
                 strict: bool = True) -> np.ndarray:
    """``(n, 2)`` (x, y) metres in the rectangle centred on the origin, pairwise ≥ ``min_dist``
    (Poisson-disk, :func:`poisson_disk`, then ``n`` chosen at random). Deterministic per seed."""
    if n < 0 or not (width_m > 0 and depth_m > 0):
        raise InputError(f"forest area {width_m} × {depth_m} m is empty; give a positive width and depth")
    if n == 0:
        return np.zeros((0, 2))
    rng = np.random.default_rng(seed)
    if not min_dist > 0:
        return rng.uniform([-width_m / 2, -depth_m / 2], [width_m / 2, depth_m / 2], (n, 2))
    pts = poisson_disk(width_m, depth_m, min_dist, rng)
    if len(pts) < n:
        _too_few(n, len(pts), f"in {width_m:g} × {depth_m:g} m", min_dist, strict)
    pick = rng.permutation(len(pts))[:n]
    return pts[pick] - [width_m / 2, depth_m / 2]


def scatter_on_mesh(n: int, triangles: np.ndarray, min_dist: float, seed: int = 0,
                    strict: bool = True, candidates_per_tree: int = 40) -> np.ndarray:
    """``(n, 3)`` points on ``triangles (T, 3, 3)`` (world metres), pairwise ≥ ``min_dist``:
    area-weighted candidates accepted in random order by dart throwing. Deterministic per seed."""
    tri = np.asarray(triangles, np.float64)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3) or len(tri) == 0:
        raise InputError(f"the ground mesh has no triangles (shape {tri.shape}); select a mesh with faces")
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not np.isfinite(area).all() or area.sum() <= 0:
        raise InputError("the ground mesh has no area; select a mesh with faces")
    if n == 0:
        return np.zeros((0, 3))
    rng = np.random.default_rng(seed)
    m = max(int(candidates_per_tree * n), 1000)
    t = rng.choice(len(tri), size=m, p=area / area.sum())
    u, v = rng.random(m), rng.random(m)
    su = np.sqrt(u)
    w = np.stack([1 - su, su * (1 - v), su * v], 1)                   # uniform barycentric
    cand = np.einsum("mk,mkd->md", w, tri[t])
    if not min_dist > 0:
        return cand[:n]
    cell = float(min_dist)
    keys = np.floor(cand / cell).astype(np.int64)
    grid: dict = {}
    out: list = []
    off = [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)]
    r2 = min_dist * min_dist
    for idx in range(m):
        c, key = cand[idx], keys[idx]
        ok = True
        for o in off:
            for q in grid.get((key[0] + o[0], key[1] + o[1], key[2] + o[2]), ()):
                if np.sum((out[q] - c) ** 2) < r2:
                    ok = False
                    break
            if not ok:
                break
        if ok:
            grid.setdefault((int(key[0]), int(key[1]), int(key[2])), []).append(len(out))
            out.append(c)
            if len(out) == n:
                break
    if len(out) < n:
        _too_few(n, len(out), "on the ground mesh", min_dist, strict)
    return np.asarray(out).reshape(-1, 3)


@dataclass
class ForestSettings:
    """``variants``: how many distinct trees a forest grows; its trees are these variants, each
    standing several times, turned, sized and out of step (0: every tree its own). The panel's
    *Variants* reads this default and range."""

    variants: int = param(3, 0, 1000, what="forest variants")


@dataclass
class TreeSlot:
    """One forest tree: ``position (3,)`` metres, ``rotation_z`` radians, ``seed``,
    ``time_offset_s`` (sway shifted in time), ``tree_phase (3,)`` radians, ``scale`` (size factor),
    ``variant``: which grown tree stands here (an index into :func:`generate_forest`'s list)."""

    position: np.ndarray
    rotation_z: float
    seed: int
    time_offset_s: float
    tree_phase: np.ndarray
    scale: float
    variant: int = 0


def forest_slots(positions: np.ndarray, seed: int = 0, scale_jitter: float = 0.1,
                 max_offset_s: float = 10.0, variants: int = 0) -> list[TreeSlot]:
    """Per position ``(n, 2 or 3)`` a :class:`TreeSlot` with a random rotation about z, a random
    time offset in [0, ``max_offset_s``) and tree phase, and a size factor in ``1 ± scale_jitter``.

    ``variants`` 0 (or ≥ n): every slot its own tree (a distinct seed, ``variant = i``). Else the
    slots are dealt among ``variants`` trees, as evenly as n allows and in random order (variant
    ``v``'s seed on each of its slots; the variants numbered by their first slot). Deterministic
    per seed."""
    P = np.asarray(positions, np.float64)
    if P.ndim != 2 or P.shape[1] not in (2, 3):
        raise InputError(f"tree positions have shape {P.shape}; expected (n, 2) or (n, 3)")
    if int(variants) < 0:
        raise InputError(f"forest variants {variants} out of range; use 0 (every tree its own) or more")
    if P.shape[1] == 2:
        P = np.concatenate([P, np.zeros((len(P), 1))], 1)
    n = len(P)
    ss = np.random.SeedSequence([int(seed) & 0xFFFFFFFF, 0xF0E])
    rng = np.random.default_rng(ss)
    seeds = ss.generate_state(n, np.uint32) if n else np.zeros(0, np.uint32)
    slots = [TreeSlot(P[i], float(rng.uniform(0, 2 * np.pi)), int(seeds[i]), float(rng.uniform(0, max_offset_s)),
                      rng.uniform(0, 2 * np.pi, 3), float(1.0 + scale_jitter * rng.uniform(-1, 1)), i)
             for i in range(n)]
    if 0 < int(variants) < n:
        dealt = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x7A5]).permutation(np.arange(n) % int(variants))
        _, first, which = np.unique(dealt, return_index=True, return_inverse=True)
        order = np.argsort(np.argsort(first))              # variants numbered by their first slot
        for i, s in enumerate(slots):
            s.variant = int(order[which[i]])
            s.seed = int(seeds[int(np.sort(first)[s.variant])])
    return slots


def variant_count(slots: list[TreeSlot]) -> int:
    """How many grown trees ``slots`` stand on (their largest variant + 1; 0 without slots)."""
    return max((s.variant for s in slots), default=-1) + 1


def shares_variants(slots: list[TreeSlot]) -> bool:
    """True if some variant stands in more than one slot."""
    return variant_count(slots) < len(slots)


def instance_offsets(slots: list[TreeSlot], fps: float, period_frames: int) -> np.ndarray:
    """``(n,)`` whole frames in [0, ``period_frames``): how far into its variant's loop each slot
    plays at the first frame — its time offset minus the one its variant was grown with (the
    variant's first slot, 0 there), rounded to frames and wrapped round the period."""
    if period_frames < 1:
        raise ValueError(f"period_frames {period_frames} must be ≥ 1")
    grown: dict[int, float] = {}
    for s in slots:
        grown.setdefault(s.variant, s.time_offset_s)
    rel = np.array([s.time_offset_s - grown[s.variant] for s in slots], np.float64)
    return np.mod(np.rint(rel * float(fps)).astype(np.int64), int(period_frames))


def generate_forest(model, envelope, slots: list[TreeSlot], params=None, audio=None,
                    progress: ProgressFn | None = None) -> list:
    """One :class:`~.tree3d.Tree3D` per variant (``slots[i].variant`` indexes the list), grown with
    its first slot's seed, phase, offset and size, in the tree's own frame (place it at
    ``slot.position`` rotated by ``slot.rotation_z``; a later slot of the variant scaled by
    ``slot.scale / first.scale`` and played from :func:`instance_offsets`). Without shared
    variants that is a distinct tree per slot, as before.

    A shared variant sways in a loop (``meta["periodic"]``): ``params.loop_s`` if set, else the
    forest's length (``n_frames − 1`` frames, the last frame the first), so any of its slots can
    start anywhere in it.

    ``params`` a :class:`.growth.GrowParams` template; ``audio`` a WAV path or an envelope —
    read once and shared, so a gust reaches every tree at the same time (then every slot needs its
    own tree: shared variants would carry the gust at different times). Cancellable."""
    from .growth import GrowParams, grow_tree
    from .wind import audio_envelope
    base = params or GrowParams()
    fps = float(base.fps or model.fps)
    shared = shares_variants(slots)
    if shared and audio is not None:
        raise InputError("a recorded wind reaches every tree at the same time, so trees cannot share a "
                         "variant; set the forest's Variants to 0")
    if shared and not base.loop_s > 0:
        base = replace(base, loop_s=max(int(base.n_frames) - 1, 2) / fps)
    if audio is not None and not isinstance(audio, np.ndarray):
        audio = audio_envelope(audio, fps, int(base.n_frames))
    env_h = float(np.max(envelope.z))
    first: dict[int, tuple[int, TreeSlot]] = {}
    for k, s in enumerate(slots):
        first.setdefault(s.variant, (k, s))
    if sorted(first) != list(range(len(first))):
        raise ValueError(f"slot variants {sorted(first)} are not 0..{len(first) - 1}")
    out = []
    V = len(first)
    for v in range(V):
        k, s = first[v]
        report(progress, "forest", v / max(V, 1))
        height = (base.height_m or env_h) * s.scale
        p = replace(base, seed=s.seed, time_offset_s=s.time_offset_s, tree_phase=tuple(s.tree_phase),
                    height_m=height, name=f"{base.name or model.name}_{k:03d}")
        out.append(grow_tree(model, envelope, p, audio, sub_progress(progress, v / V, (v + 1) / V)))
    report(progress, "forest", 1.0)
    return out
