"""Geometry of the skinned branch mesh (pure numpy; ``operators/scene/branch_mesh.py`` puts it in Blender).

One closed tube per bone, ``K`` rings of ``S`` vertices each, capped at both ends:

* **Curliness** (paper §3.3, Flash & Hogan): the tube's centre line is the bone bent by a lateral
  offset along the minimum-jerk profile of :func:`details.curly_branch`,
  ``c(τ) = head + τ (tail − head) + o · 4 s(τ)(1 − s(τ))``, ``s = 10τ³ − 15τ⁴ + 6τ⁵``. The offset
  ``o`` is perpendicular to the bone, ``|o| ≤ curliness ·`` :data:`CURL_SHARE` ``· length``
  (deterministic per seed). Its lateral velocity vanishes at both ends, so the curve leaves the head
  and reaches the tail along the straight bone: where a child continues its parent the joint has
  exactly the bones' own angle (curliness adds no kink). Rings are perpendicular to the curve.
* **Bark**: every ring's radius is ``r(θ) = r0 (1 + Σ_i b_i sin(ω_i θ + φ_i))`` (:func:`details.bark_radius`)
  with integer ω_i (below S/2, so 8-sided tubes do not alias), so each ring closes seamlessly;
  ``b_i`` from :data:`details.BARK_PRESETS` ("smooth": Σ b ≤ 0.5 %, "rough": 1–5 % of r0).
  The phases drift with the arc length (the ridges wind slowly and continue from a branch into
  the child that continues it).
* **UVs**: ``u`` around (one unit a turn, a seam at θ = 0), ``v`` = arc length of the centre line from the
  trunk base ÷ the thickest tube's circumference (square texels on the trunk): continuous along a
  branch (``v`` at a child's head equals ``v`` at its parent's tail). Each ring's ``u`` starts at
  ``u0`` (:func:`up_offsets`) so that ``u ≡`` :data:`U_UP` (mod 1) on the tube's upper side: the bark
  texture's band there (the moss of :func:`.bark_photo.uv_square`) lies on top of every branch in
  every format, with no per-vertex data.
* **Weights**: every ring belongs to its bone with weight 1 (``vert_bone``).

With ``curliness = 0`` and ``bark = "none"`` the default is 2 rings per bone: the straight tapered
tubes of earlier versions, vertex for vertex.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import bones, rotations
from ..errors import InputError
from ..params import check, param
from .forks import plan_forks as fork_plan
from .shapes import BARK_PRESETS, minimum_jerk, random_bark

#: the largest lateral offset of a curly tube at curliness 1, share of its bone's length
CURL_SHARE = 0.12
#: the ``u`` (mod 1) of every ring's upper side (:func:`up_offsets`)
U_UP = 0.5
#: world up and the side a vertical trunk's ``U_UP`` faces: +Y, Blender's north (the Sun Position
#: add-on's North at offset 0), the shaded side where moss grows on a trunk in the northern hemisphere
UP_AXIS = np.array([0.0, 0.0, 1.0])
NORTH_AXIS = np.array([0.0, 1.0, 0.0])
#: rings per bone when curly (``rings = 0``)
CURLY_RINGS = 6
#: bark phase drift, radians per unit of v (one texture tile), at most
BARK_DRIFT = 1.0
BARK_KINDS = ("none",) + tuple(BARK_PRESETS)
#: how tubes meet at a node: one closed surface, or tubes that interpenetrate (:mod:`core.detail.forks`)
FORK_KINDS = ("joined", "overlap")


@dataclass
class MeshParams:
    """Branch mesh settings: ``sides`` S ≥ 3 vertices per ring; ``curliness`` 0..1; ``bark`` one of
    :data:`BARK_KINDS`; ``rings`` K per bone (0 = automatic: 2 if straight, :data:`CURLY_RINGS`
    if curly); ``seed`` for the offsets and the bark; ``forks`` one of
    :data:`FORK_KINDS` (how tubes meet at a node); ``relief_cm`` the bark's height map as geometry,
    its depth on the thickest tube in cm (0: none; :mod:`core.detail.relief`)."""

    sides: int = 8
    curliness: float = param(0.3, 0.0, 1.0, what="curliness")
    bark: str = param("rough", choices=BARK_KINDS, what="bark")
    rings: int = 0
    seed: int = 0
    forks: str = param("joined", choices=FORK_KINDS, what="forks")
    relief_cm: float = param(0.0, 0.0, 20.0, what="bark relief", unit="cm")

    def ring_count(self) -> int:
        if self.rings:
            return int(self.rings)
        return CURLY_RINGS if self.curliness > 0 else 2


def check_params(p: MeshParams) -> None:
    """Raise :class:`InputError` naming a bad setting."""
    if not isinstance(p.sides, (int, np.integer)) or p.sides < 3:
        raise InputError(f"tubes need at least 3 sides (got {p.sides})")
    if p.forks not in FORK_KINDS:
        raise InputError(f"unknown forks '{p.forks}'; choose one of {', '.join(FORK_KINDS)}")
    if p.bark not in BARK_KINDS:
        raise InputError(f"unknown bark '{p.bark}'; choose one of {', '.join(BARK_KINDS)}")
    check(p)
    if p.rings and p.rings < 2:
        raise InputError(f"a tube needs at least 2 rings per bone (got {p.rings})")


def branch_radii(parents: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tube radii at each bone's head and tail, ``(B,)`` each, metres.

    The tail takes its node's radius. The head takes the parent node's radius if the bone
    continues its parent branch (it is the thickest child), else the smaller of the two: a side
    branch starts as thick as itself, not as the trunk it leaves."""
    edges = bones.bone_edges(parents)
    radius = np.asarray(radius, np.float64)
    r_tail = radius[edges[:, 1]]
    thickest = np.zeros(len(parents))
    np.maximum.at(thickest, edges[:, 0], r_tail)
    main = r_tail >= thickest[edges[:, 0]]
    r_head = np.where(main, radius[edges[:, 0]], np.minimum(radius[edges[:, 0]], r_tail))
    return r_head, r_tail


def bark_terms(kind: str, sides: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(amplitudes, freqs, phases, drift)`` of the bark ``kind`` for ``sides``-gon rings: the terms
    of :func:`details.random_bark` with each integer frequency folded below S/2
    (``ω ← 2 + (ω − 2) mod (S/2 − 2)`` for S ≥ 8, else 1), plus a phase drift per term in
    ±:data:`BARK_DRIFT` rad per unit of v. ``"none"`` gives empty arrays."""
    if kind == "none":
        z = np.zeros(0)
        return z, z.astype(np.int64), z, z
    amp, freqs, phases = random_bark(kind, seed=seed)
    top = sides // 2 - 1                       # highest frequency an S-gon shows without aliasing
    freqs = np.where(top >= 3, 2 + (freqs - 2) % max(top - 1, 1), 1).astype(np.int64)
    drift = np.random.default_rng(seed + 7919).uniform(-BARK_DRIFT, BARK_DRIFT, len(amp))
    return amp, freqs, phases, drift


def _arc_lengths(parents, edges, parent_bone, length):
    """Arc length ``(N,)`` from the root to every node along bones of ``length (B,)``."""
    arc = np.zeros(len(parents))
    depth = bones.bone_depths(parent_bone)
    for d in range(depth.max() + 1):
        idx = np.flatnonzero(depth == d)
        arc[edges[idx, 1]] = arc[edges[idx, 0]] + length[idx]
    return arc


def curl_offsets(rest: np.ndarray, length: np.ndarray, curliness: float, seed: int) -> np.ndarray:
    """Lateral offsets ``o (B, 3)`` metres: perpendicular to each bone (``rest (B, 3, 3)``, Y along
    the bone), direction uniform about it, size ``curliness · CURL_SHARE · length · m`` with ``m``
    uniform in [0.5, 1] (deterministic per ``seed``)."""
    B = len(length)
    if curliness <= 0 or B == 0:
        return np.zeros((B, 3))
    rng = np.random.default_rng(seed)
    psi = rng.uniform(0, 2 * math.pi, B)
    m = rng.uniform(0.5, 1.0, B)
    d = np.cos(psi)[:, None] * rest[:, :, 0] + np.sin(psi)[:, None] * rest[:, :, 2]
    return (curliness * CURL_SHARE * length * m)[:, None] * d


def _frames(head: np.ndarray, seg: np.ndarray, offset: np.ndarray, rest: np.ndarray, tau: np.ndarray,
            curly: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The centre line at ``tau (M, K)`` along bones ``head``, ``seg = tail − head``, ``offset (M,
    3)`` (the minimum-jerk bump on [0, 1] only; straight beyond) and the rings' axes: ``centre``,
    unit ``tangent``, ``rx``, ``rz`` each ``(M, K, 3)`` (the bone's X/Z of ``rest (M, 3, 3)`` swung,
    without twist, from its Y onto the tangent)."""
    tc = np.clip(tau, 0.0, 1.0)
    s = minimum_jerk(tc)
    bump = 4.0 * s * (1.0 - s)
    dbump = 4.0 * (1.0 - 2.0 * s) * 30.0 * tc ** 2 * (1.0 - tc) ** 2 * (tau > 0) * (tau < 1)
    centre = head[:, None] + tau[..., None] * seg[:, None] + bump[..., None] * offset[:, None]
    tangent = seg[:, None] + dbump[..., None] * offset[:, None]
    tangent = tangent / np.linalg.norm(tangent, axis=-1, keepdims=True)
    axis_x, axis_y, axis_z = rest[:, :, 0], rest[:, :, 1], rest[:, :, 2]
    if curly:
        q = rotations.swing(np.broadcast_to(axis_y[:, None], tangent.shape), tangent)           # (M, K, 4)
        rx = rotations.quat_rotate(q, np.broadcast_to(axis_x[:, None], tangent.shape))
        rz = rotations.quat_rotate(q, np.broadcast_to(axis_z[:, None], tangent.shape))
    else:                                       # straight: exactly the rest axes (Blender's float32)
        rx = np.broadcast_to(axis_x[:, None], tangent.shape)
        rz = np.broadcast_to(axis_z[:, None], tangent.shape)
    return centre, tangent, rx, rz


def up_offsets(chord: np.ndarray, rx: np.ndarray, rz: np.ndarray) -> np.ndarray:
    """``u0 (B, K)``: the ``u`` at θ = 0 of each tube's rings such that the tube's upper side is at
    ``u ≡`` :data:`U_UP`; one value per tube (a tube's bark never twists along it).

    The tube's reference side is ``a + (1 − |a|)² n``: ``a`` world up minus its part along the
    bone's unit ``chord (B, 3)`` (head to tail), ``n`` the same of :data:`NORTH_AXIS` (a vertical
    trunk has no upper side and takes north; a level branch takes up; in between they blend). Its
    angle in each ring (``φ = atan2(ref · rz, ref · rx)``, ring vertex ``k`` at θ_k = 2πk/S;
    ``rx``, ``rz`` ``(B, K, 3)``), averaged over the tube's rings on the circle, gives
    ``u0 = U_UP − φ / 2π`` in [0, 1). The blend has a zero (a direction on the sphere with no
    reference side: any tangent field has one), a bone leaning ~22° from vertical toward the north;
    a tube there takes an arbitrary but untwisted ``u0``."""
    t = np.asarray(chord, np.float64)
    a = UP_AXIS - (t @ UP_AXIS)[:, None] * t
    n = NORTH_AXIS - (t @ NORTH_AXIS)[:, None] * t
    w = (1.0 - np.minimum(np.linalg.norm(a, axis=-1), 1.0)) ** 2
    ref = (a + w[:, None] * n)[:, None]
    phi = np.arctan2(np.sum(ref * rz, axis=-1), np.sum(ref * rx, axis=-1))        # (B, K)
    mean = np.arctan2(np.sin(phi).sum(axis=1), np.cos(phi).sum(axis=1))
    u0 = np.mod(U_UP - mean / (2.0 * math.pi), 1.0)
    return np.broadcast_to(u0[:, None], phi.shape).copy()


def tube_arrays(rest_pos: np.ndarray, parents: np.ndarray, rest: np.ndarray, r_head: np.ndarray,
                r_tail: np.ndarray, sides: int = 8, *, curliness: float = 0.0, bark: str = "none",
                rings: int = 0, seed: int = 0, forks: str = "overlap", pipe_exponent: float = 2.0) -> dict:
    """Geometry of one closed tube per bone (see the module docstring).

    ``rest_pos (N, 3)`` metres, ``rest (B, 3, 3)`` bone rest rotations (Y along the bone; rings of
    straight tubes lie in the bones' X/Z planes), radii ``(B,)`` metres at head and tail (linear
    taper). With ``forks="overlap"`` each tube of a bone with a parent bone starts ``ext = r_head``
    (at most half the parent's length) before its head, straight along the bone, inside the parent's
    tube, so joints stay closed when the tree bends; ``K`` rings are spread evenly from there to the
    tail. With ``forks="joined"`` the tubes end in rings short of every node and the nodes' junctions
    (:mod:`core.detail.forks`; the continuing child's head radius by the pipe model with
    ``pipe_exponent``) make one closed surface; the bark's relief fades out on those rings.

    Returns arrays: ``co (V, 3)``; ``loop_vert (L,)``; ``loop_start``, ``loop_total``, ``smooth (P,)``;
    ``uv (L, 2)``; ``vert_bone (V,)``; per ring ``centre (B, K, 3)``, ``tangent (B, K, 3)`` (unit),
    ``r0 (B, K)`` (radius before bark), ``tau (B, K)`` (position along the bone: 0 head, 1 tail,
    < 0 in the extension), ``v (B, K)``, ``u0 (B, K)`` (:func:`up_offsets`); ``bark`` =
    :func:`bark_terms`; ``tile`` (metres per unit of v); ``plan`` the
    :class:`~core.detail.forks.ForkPlan` (joined only). ``V = K·S·B``; ring ``j`` of bone ``b`` is
    vertices ``(b·K + j)·S … + S − 1``, vertex ``k`` at angle ``θ_k = 2πk/S`` from the ring's X.
    Overlapping: ``P = ((K − 1)·S + 2)·B``, ``L = (4(K − 1) + 2)·S·B``, polygons contiguous
    per bone."""
    p = MeshParams(int(sides), float(curliness), bark, int(rings), int(seed), forks)
    check_params(p)
    S, K = p.sides, p.ring_count()
    edges = bones.bone_edges(parents)
    parent_bone = bones.bone_parents(parents)
    B = len(edges)
    P0 = np.asarray(rest_pos, np.float64)
    rest = np.asarray(rest, np.float64)
    r_head = np.asarray(r_head, np.float64)
    r_tail = np.asarray(r_tail, np.float64)
    head, tail = P0[edges[:, 0]], P0[edges[:, 1]]
    seg = tail - head
    length = np.linalg.norm(seg, axis=1)
    ext = np.where(parent_bone >= 0, np.minimum(r_head, 0.5 * length[np.maximum(parent_bone, 0)]), 0.0)
    offset = curl_offsets(rest, length, p.curliness, p.seed)                            # (B, 3)
    curly = p.curliness > 0
    theta = 2 * math.pi * np.arange(S) / S
    plan = None
    if p.forks == "joined":
        def ring_points(b, t, r):
            c, _, x, z = _frames(head[b], seg[b], offset[b], rest[b], t[:, None], curly)
            ring = np.cos(theta)[None, :, None] * x[:, 0, None] + np.sin(theta)[None, :, None] * z[:, 0, None]
            return c[:, 0, None] + r[:, None, None] * ring

        def tangents(b, t):
            return _frames(head[b], seg[b], offset[b], rest[b], t[:, None], curly)[1][:, 0]
        plan = fork_plan(parents, length, r_head, r_tail, ext, ring_points, tangents, S, float(pipe_exponent))
        r_head = plan.r_head
        tau0, tau1 = plan.tau_start, plan.tau_end
    else:
        tau0, tau1 = -ext / np.maximum(length, 1e-12), np.ones(B)

    # centre line: rings evenly from τ0 to τ1; the minimum-jerk bump on [0, 1] only
    tau = tau0[:, None] + (tau1 - tau0)[:, None] * np.linspace(0.0, 1.0, K)[None]      # (B, K)
    centre, tangent, rx, rz = _frames(head, seg, offset, rest, tau, curly)

    # arc length along the curved centre lines (ring to ring over [0, 1], ×1 for straight tubes)
    if curly:
        fine = np.linspace(0.0, 1.0, 33)
        sf = minimum_jerk(fine)
        pts = head[:, None] + fine[None, :, None] * seg[:, None] + (4 * sf * (1 - sf))[None, :, None] * offset[:, None]
        curve_len = np.linalg.norm(np.diff(pts, axis=1), axis=-1).sum(axis=1)
    else:
        curve_len = length
    arc = _arc_lengths(parents, edges, parent_bone, curve_len)
    tile = 2 * math.pi * max(float(np.max(r_head)) if B else 0.0, 1e-6)
    v = (arc[edges[:, 0]][:, None] + tau * curve_len[:, None]) / tile                    # (B, K)

    # radius per ring (linear taper in τ from head to tail; the extension keeps r_head) and bark
    w = np.clip(tau, 0.0, 1.0)
    r0 = r_head[:, None] * (1.0 - w) + r_tail[:, None] * w                              # (B, K)
    amp, freqs, phases, drift = bark_terms(p.bark, S, p.seed)
    if len(amp):
        ph = phases[None, None] + drift[None, None] * v[..., None]                       # (B, K, T)
        wave = np.sum(amp * np.sin(freqs * theta[:, None, None, None] + ph[None]), axis=-1)   # (S, B, K)
        wave = np.moveaxis(wave, 0, -1)                                                 # (B, K, S)
        if plan is not None:                   # a junction's rings keep the hull's circles
            wave[~plan.head_cap, 0] = 0.0
            wave[~plan.tail_cap, -1] = 0.0
        radius = r0[..., None] * (1.0 + wave)
    else:
        radius = np.broadcast_to(r0[..., None], (B, K, S))
    ring = np.cos(theta)[None, None, :, None] * rx[:, :, None] + np.sin(theta)[None, None, :, None] * rz[:, :, None]
    co = centre[:, :, None] + radius[..., None] * ring                                   # (B, K, S, 3)

    # faces: side quads ring j → j+1, then the head cap (ring 0) and the tail cap (ring K−1)
    k = np.arange(S)
    kn = (k + 1) % S
    j = np.arange(K - 1)[:, None]
    side = np.stack([j * S + k, (j + 1) * S + k, (j + 1) * S + kn, j * S + kn], axis=-1).reshape(-1)
    head_cap = k                                                                         # normal −tangent
    tail_cap = (K - 1) * S + k[::-1]                                                     # normal +tangent
    per_bone = np.concatenate([side, head_cap, tail_cap])                                # ((4(K−1)+2)S,)
    n_loops = len(per_bone)
    loop_vert = (per_bone[None] + K * S * np.arange(B)[:, None]).ravel()
    totals = np.concatenate([np.full((K - 1) * S, 4), [S, S]])
    starts = np.concatenate([[0], np.cumsum(totals)[:-1]])
    loop_start = (starts[None] + n_loops * np.arange(B)[:, None]).ravel()
    loop_total = np.tile(totals, B)
    smooth = np.tile(np.concatenate([np.ones((K - 1) * S, bool), [False, False]]), B)

    u_side = np.tile(np.stack([k, k, k + 1, k + 1], axis=1).ravel() / S, K - 1)         # (4S(K−1),)
    ring_of_loop = np.broadcast_to(j[:, :, None] + np.array([0, 1, 1, 0]), (K - 1, S, 4)).reshape(-1)
    u0 = up_offsets(seg / np.maximum(length, 1e-12)[:, None], rx, rz)                     # (B, K)
    u_cap = 0.5 + np.cos(theta) / (2 * math.pi)
    uv = np.empty((B, n_loops, 2))
    ns = 4 * S * (K - 1)
    uv[:, :ns, 0] = u_side[None] + u0[:, ring_of_loop]
    uv[:, :ns, 1] = v[:, ring_of_loop]
    uv[:, ns:ns + S, 0] = u_cap
    uv[:, ns:ns + S, 1] = v[:, :1] + (r0[:, :1] / tile) * np.sin(theta)[None]
    uv[:, ns + S:, 0] = u_cap[::-1]
    uv[:, ns + S:, 1] = v[:, -1:] + (r0[:, -1:] / tile) * np.sin(theta[::-1])[None]
    out = {"co": co.reshape(-1, 3), "loop_vert": loop_vert, "loop_start": loop_start,
           "loop_total": loop_total, "smooth": smooth, "uv": uv.reshape(-1, 2),
           "vert_bone": np.repeat(np.arange(B), K * S), "centre": centre, "tangent": tangent,
           "r0": r0, "tau": tau, "v": v, "u0": u0, "bark": (amp, freqs, phases, drift), "tile": tile,
           "rings": K, "sides": S, "plan": plan}
    if plan is not None:
        out.update(joined_polygons(out, plan, K, S, v))
    return out


def joined_polygons(g: dict, plan, K: int, S: int, v: np.ndarray) -> dict:
    """The polygons of joined tubes: each bone's side quads, the caps only where a tube ends
    unjoined (the root's foot, the tips, a fork left overlapping), then the junctions' triangles and
    the bends' quads (smooth; their loops' UVs the rings' own ``(k/S + u0, v)``, moved by whole
    turns to one piece of the texture per face)."""
    n_loops = (4 * (K - 1) + 2) * S
    totals = np.concatenate([np.full((K - 1) * S, 4), [S, S]])
    B = len(plan.head_cap)
    keep = np.ones((B, len(totals)), bool)
    keep[:, -2] = plan.head_cap
    keep[:, -1] = plan.tail_cap
    keep_poly = keep.ravel()
    loop_keep = np.repeat(keep_poly, g["loop_total"])
    tris, quads = plan.polygons(K, S)
    extra = np.concatenate([tris.ravel(), quads.ravel()]).astype(np.int64)
    loop_vert = np.concatenate([g["loop_vert"][loop_keep], extra])
    loop_total = np.concatenate([g["loop_total"][keep_poly], np.full(len(tris), 3), np.full(len(quads), 4)])
    loop_start = np.concatenate([[0], np.cumsum(loop_total)[:-1]])
    smooth = np.concatenate([g["smooth"][keep_poly], np.ones(len(tris) + len(quads), bool)])
    # the extra faces' UVs: (k / S + u0 of the vertex's ring, v of its ring), each vertex's u moved by
    # whole turns to within half a turn of its face's first vertex (a face across the seam, or between
    # rings whose u0 differ, stays one piece of the texture)
    kk = extra % S
    ring = extra // S                                                  # b·K + j
    u = kk / S + g["u0"].reshape(-1)[ring]
    face = np.concatenate([np.repeat(np.arange(len(tris)), 3), len(tris) + np.repeat(np.arange(len(quads)), 4)])
    first = np.concatenate([np.arange(len(tris)) * 3, 3 * len(tris) + np.arange(len(quads)) * 4])
    u = u + np.round(u[first][face] - u)
    uv_extra = np.stack([u, v.reshape(-1)[ring]], axis=1)
    uv = np.concatenate([g["uv"].reshape(B, n_loops, 2).reshape(-1, 2)[loop_keep], uv_extra])
    return {"loop_vert": loop_vert, "loop_start": loop_start, "loop_total": loop_total, "smooth": smooth,
            "uv": uv}


def mesh_stats(g: dict) -> dict:
    """``{"vertices", "faces", "triangles"}`` of :func:`tube_arrays` output (a quad is 2
    triangles, an S-gon cap S − 2)."""
    tris = int(np.sum(g["loop_total"] - 2))
    return {"vertices": len(g["co"]), "faces": len(g["loop_start"]), "triangles": tris}
