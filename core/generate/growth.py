"""Grow a new tree from a species model inside an envelope Ω' (paper §5.3).

1. **2D growth** (x, z metres, in Ω'). A trunk goes straight up from the origin to the first
   bifurcation (``trunk_frac`` of the height, at least to where Ω' widens). Then, until the node
   budget is spent, no growing tip is left, or Ω' is filled: pick a random growing tip ``i``
   (its branch comes from the anchor ``j``, length ``L1``), sample ``⟨θ1:θ2:θ3⟩`` and
   ``⟨L1:L2:L3⟩`` from the model's Dirichlets and a turning sense ``s = ±1`` (clockwise with
   the example's share ``mirror_p``), so the continuing child leaves ``i`` at ``β + s·2πθ1`` and
   the side child at ``β + s·2π(θ1 + θ2)`` (β the direction back to ``j``; see
   :func:`.features.canonical_angles`) with lengths ``L1·L2/L1`` and ``L1·L3/L1``. The growing
   direction is a 1-D search over a rotation φ of the pair about the view axis (L candidates in
   ±``max_turn``, keeping every angle ≥ 10°),
   maximizing, as in the lift (Eq. 2–6 in 2D),

       p(φ) ∝ exp(−φ² / 2σ²) · E(φ) / Σ_l E(φ_l) · [both branches inside Ω']
       E(φ)  = Σ_k max(d_k − min(d_k, dist(ω_k, new branches(φ))), 0)     (Eq. 5–6)

   with ``ω_k`` ≈250 attractors spread over Ω' and ``d_k`` their distance to the tree so far.
   The angle term's centre is the sampled bifurcation (φ = 0): the angle between the new pair and
   its parent branch should look like the example's. Where all ``E`` are 0 the angle term decides.
   One factor the paper does not have, ``Π_c exp(−(γ_c − γ̄)² / 2σ_γ²)`` with ``γ_c`` each new
   branch's angle from the vertical and (γ̄, σ_γ) the example's (``orientation_deg``): the
   features are rotation invariant, so without it every generation turns ±35° at random and
   limbs curl into hooks and loops (measured: it is what made generated crowns look like trees).
   If no candidate fits, the pair is shrunk (×0.75, then ×0.5 and ×0.35 with twice the turning
   range); if none still fits the tip stops. Children are at most 4× the example's median branch.
   Branches shorter than the example's 5th-percentile branch stop growing.
2. Each branch is split into bones of about the example's bone length (slightly bent by a
   minimum-jerk bump, :func:`..detail.shapes.curly_branch`, where that stays inside Ω').
3. **Lift** with the reconstruction's Bayesian push (:func:`..reconstruct.lift.lift`) on a raster of Ω'.
4. **Motion** from sampled spectra (:mod:`.sway`), scaled by wind × audio (:mod:`.wind`).
5. **Twigs** copied from the new tree's own forks (:func:`..detail.twigs.add_twigs`, ``twig_depth``
   generations, riding on their branches' motion), as a reconstruction draws them: the fine
   branching the node budget leaves out, which the foliage hangs on. Not on palms (fronds).

Deterministic per seed: the same seed and parameters give the same tree.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace

import numpy as np

from ..detail.branch_mesh import MeshParams
from ..detail.twigs import TwigParams, add_twigs
from ..envelope import Envelope
from ..errors import InputError
from ..loop import LoopSettings
from ..meta import TreeMeta
from ..outline import Outline, polygon_to_mask
from ..params import check, param, same_as
from ..progress import ProgressFn, report, sub_progress
from ..reconstruct.lift import LiftParams, lift
from ..reconstruct.skeleton2d import Skeleton2D
from ..topology import branching_level
from ..tree3d import Tree3D, pipe_radii
from ..tree_cut import load_cut
from .allometry import allometry_report, holton_pose
from .crown_space import contour_space, varied_envelope, varied_leaf_colour
from .cuts import CutSpec, place_cuts, segment_distances
from .envelopes import RASTER_ROWS, Region2D, envelope_meta, region_of
from .species import SpeciesModel, library_contours
from .sway import forward_kinematics, sample_rotations
from .sway_fit import SWAY_OUTSIDE as SWAY_OUTSIDE  # re-exported: the sway's bounds, read by the tests
from .sway_fit import SWAY_OUTSIDE_FRAME as SWAY_OUTSIDE_FRAME
from .sway_fit import SWAY_SLACK as SWAY_SLACK
from .sway_fit import contain_sway, match_excursion
from .wind import audio_envelope, gain_curve

MIN_ANGLE = np.radians(10.0)
RASTER_HEIGHT_PX = 400.0         # the lift runs on a raster of Ω' this many pixels tall


@dataclass
class GrowParams:
    """Controls of :func:`grow_tree`.

    ``seed``; ``height_m`` scales the envelope to this height (None: keep it); ``node_budget``
    total nodes (bones + 1); ``n_frames``, ``fps`` (None: the model's); ``wind`` amplitude factor;
    ``time_offset_s`` shifts the sway in time (forests); ``tree_phase (3,)`` radians per axis
    (None: random from the seed); ``candidates`` growth directions per bifurcation,
    ``max_turn_deg`` their range, ``angle_sigma_deg`` σ of the angle term; ``attractors`` on Ω';
    ``fill_tol`` stop when the mean attractor distance is below this share of the height;
    ``length_reversion`` κ, pull of each new pair's scale toward the example's median branch;
    ``tropism`` weigh growth directions by the example's branch orientations;
    ``segments`` bones per branch (None: from the model's bone length); ``bend`` lateral bump of a
    branch (share of its length); ``lift_candidates`` / ``lift_attractors`` of the push;
    ``tip_radius`` share of the height and ``pipe_exponent`` of the pipe-model radii (None: fitted
    so the trunk and the tips are as wide as the source's, :func:`species_radii`; 0.0025 and 2
    for a species without widths); ``leaf_density`` passed on in
    ``meta`` for the leaf builder; ``twig_depth`` generations of twigs drawn beyond the budget's
    nodes (0: none; the reconstruction's default); ``conifer`` (None: the model's); ``name``;
    ``curliness`` and ``bark``, the branch mesh's look, recorded in ``meta["mesh"]`` as a
    reconstruction records it (the same defaults: a grown tree looks like a reconstructed one
    wherever it is built); ``loop_s`` > 0: the tree sways in a loop by construction, ``round(loop_s
    · fps) + 1`` frames (``n_frames`` ignored) on whole-period frequencies, the last frame the
    first (``meta["periodic"]``; :func:`core.loop.loop_tree` then blends nothing);
    ``envelope_variation`` 0..1: the tree grows in its own crown around the envelope's and its
    leaves take their own colour within the species' range (:mod:`.crown_space`; 0: the envelope
    and colour as given), recorded in ``meta["envelope_variation"]``; ``allometry`` Holton's angles
    at the forks; ``cuts`` tree-cuts the tree must contain (:mod:`.cuts`: each at its point or where
    it fits; the growth's budget less their bones, the rest grown around them), in ``meta["cuts"]``."""

    seed: int = 0
    height_m: float | None = None
    node_budget: int = 200
    n_frames: int = 250
    fps: float | None = None
    wind: float = 1.0
    time_offset_s: float = 0.0
    tree_phase: tuple | None = None
    candidates: int = 33
    max_turn_deg: float = 45.0
    angle_sigma_deg: float = 15.0
    attractors: int = 250
    fill_tol: float = 0.01
    length_reversion: float = 0.5
    tropism: bool = True
    segments: int | None = None
    bend: float = 0.04
    lift_candidates: int = 16
    lift_attractors: int = 128
    tip_radius: float | None = None
    pipe_exponent: float | None = None
    leaf_density: float = 1.0
    twig_depth: int = same_as(TwigParams, "depth")
    conifer: bool | None = None
    name: str | None = None
    curliness: float = same_as(MeshParams, "curliness")
    bark: str = same_as(MeshParams, "bark")
    forks: str = same_as(MeshParams, "forks")
    relief_cm: float = same_as(MeshParams, "relief_cm")
    loop_s: float = same_as(LoopSettings, "seconds")
    envelope_variation: float = param(0.0, 0.0, 1.0, what="--envelope-variation")
    allometry: bool = False
    cuts: tuple[CutSpec, ...] = ()


@dataclass
class Grown2D:
    """The 2D tree: ``parents (N,)``, ``pos (N, 2)`` (x, z) metres; ``anchor (N,)`` bool (branch
    points, tips and the root — the nodes before subdivision); ``stopped`` why growth ended."""

    parents: np.ndarray
    pos: np.ndarray
    anchor: np.ndarray
    stopped: str


def check_params(p: GrowParams) -> None:
    check(p)
    if int(p.node_budget) < 4:
        raise InputError(f"node budget {p.node_budget} is too small; give at least 4 (e.g. 200)")
    if int(p.n_frames) < 1:
        raise InputError(f"frame count {p.n_frames} must be at least 1")
    if p.fps is not None and not p.fps > 0:
        raise InputError(f"frame rate {p.fps} is not positive")
    if p.height_m is not None and not (np.isfinite(p.height_m) and p.height_m > 0):
        raise InputError(f"tree height {p.height_m} m is not positive; give e.g. 8")
    if not (np.isfinite(p.wind) and p.wind >= 0):
        raise InputError(f"wind strength {p.wind} must be ≥ 0 (1 = as in the example)")


def scale_envelope(env: Envelope, factor: float) -> Envelope:
    """``env`` scaled about the origin by ``factor`` (same type, polygon scaled too)."""
    import copy
    out = copy.copy(env)
    out.z, out.centre, out.radius = env.z * factor, env.centre * factor, env.radius * factor
    if getattr(env, "polygon", None) is not None:
        out.polygon = np.asarray(env.polygon) * factor   # type: ignore[attr-defined]
    return out


def stem_top(region: Region2D) -> float:
    """Lowest height where Ω' is at least 30 % of its widest."""
    H = region.height()
    z = np.linspace(0.0, H, 200)
    w = region.width_at(z)
    wide = np.flatnonzero(w >= 0.3 * w.max())
    return float(z[wide[0]]) if len(wide) else 0.0


#: sampled forks tried at one tip before it stops growing
MAX_FORK_TRIES = 6


def grow_2d(model: SpeciesModel, region: Region2D, p: GrowParams, rng: np.random.Generator,
            progress: ProgressFn | None = None) -> Grown2D:
    """Step 1–2 of the module docstring; metres."""
    H = region.height()
    budget = int(p.node_budget)
    seg_len = max(model.segment_frac * H, 1e-6)
    min_len = max(model.min_branch_frac * H, 1e-3 * H)
    sigma = np.radians(p.angle_sigma_deg)
    o_mean, o_std = model.orientation_deg
    turns = np.radians(p.max_turn_deg) * np.linspace(-1.0, 1.0, max(int(p.candidates), 1) | 1)
    along = np.array([0.25, 0.5, 0.75, 1.0])

    def n_seg(length: float) -> int:
        if p.segments is not None:
            return max(1, int(p.segments))
        return int(np.clip(round(length / seg_len), 1, 8))

    # trunk: straight up to the first bifurcation, at least where Ω' widens
    zt = min(max(model.trunk_frac * H, stem_top(region) + 0.02 * H), 0.6 * H)
    while zt > 0.05 * H and not region.contains(np.array([[0.0, zt]]))[0]:
        zt *= 0.9
    if not region.contains(np.array([[0.0, 0.5 * zt]]))[0]:
        raise InputError("the envelope does not contain the trunk base; the shape must reach down to its "
                         "lowest point (the origin) with some width")
    pos = [np.zeros(2), np.array([0.0, zt])]
    par = [-1, 0]
    total = 1 + n_seg(zt)
    attr = region.attractors(p.attractors)
    d_cur = segment_distances(attr, pos[0][None], pos[1][None])[0]
    live = [1]
    fails: dict[int, int] = {}
    stopped = "no growing tip left"
    steps = 0
    while live:
        if total >= budget - 1:
            stopped = "node budget reached"
            break
        if d_cur.mean() < p.fill_tol * H:
            stopped = "envelope filled"
            break
        steps += 1
        if steps % 8 == 0:
            report(progress, "growing", total / budget)
        k = int(rng.integers(len(live)))
        i = live[k]
        j = par[i]
        back = pos[j] - pos[i]
        L1 = float(np.linalg.norm(back))
        th = 2 * np.pi * _dirichlet(rng, model.angles)
        ln = _dirichlet(rng, model.lengths)
        # lengths cascade from the parent branch (L_k = L1 · l_k / l_1); the trunk is not a
        # branch of that cascade, so the first pair scales from the example's median branch
        # plus a pull toward the example's typical branch (log L_eff = (1−κ) log L1 + κ log L_typ):
        # the ratios alone are a multiplicative random walk whose lengths drift without bound
        typ = model.branch_frac * H
        scale = typ if j == 0 else float(np.exp((1 - p.length_reversion) * np.log(L1)
                                                 + p.length_reversion * np.log(typ)))
        lens = np.minimum(scale * ln[1:] / ln[0], min(4.0 * typ, 0.6 * H))   # a tiny sampled L1 share
                                                                            # would give huge children
        beta = np.arctan2(back[1], back[0])
        sense = -1.0 if rng.random() < model.mirror_p else 1.0     # clockwise = mirrored
        valid = None
        # the sampled shape first; where it does not fit, shorter and turned further
        for shrink, widen in ((1.0, 1.0), (0.75, 1.0), (0.5, 2.0), (0.35, 2.0)):
            cand = turns * widen
            ok_turn = (th[0] + cand >= MIN_ANGLE) & (th[2] - cand >= MIN_ANGLE)
            phi = cand[ok_turn] if ok_turn.any() else np.zeros(1)
            a1 = beta + sense * (th[0] + phi)                              # continuation
            a2 = beta + sense * (th[0] + th[1] + phi)                      # side branch
            dirs = np.stack([np.stack([np.cos(a1), np.sin(a1)], 1), np.stack([np.cos(a2), np.sin(a2)], 1)])  # (2, L, 2)
            ll = lens * shrink
            ends = pos[i][None, None] + dirs * ll[:, None, None]                     # (2, L, 2)
            pts = pos[i][None, None, None] + dirs[:, :, None] * (ll[:, None, None, None] * along[None, None, :, None])
            valid = region.contains(pts).all(axis=(0, 2))                            # (L,)
            if valid.any():
                break
        if valid is None or not valid.any() or ll.min() < 0.25 * min_len:
            # a tip whose sampled fork does not fit gets new samples before it stops: the first
            # fork of a small envelope failing once would otherwise leave a bare pole
            fails[i] = fails.get(i, 0) + 1
            if fails[i] >= MAX_FORK_TRIES:
                live.pop(k)
            continue
        need = n_seg(ll[0]) + n_seg(ll[1])
        if total + need > budget:            # stop here: skipping this pair would favour short ones
            stopped = "node budget reached"
            break
        dn = np.minimum(segment_distances(attr, np.repeat(pos[i][None], len(phi), 0), ends[0]),
                        segment_distances(attr, np.repeat(pos[i][None], len(phi), 0), ends[1]))   # (L, K)
        gain = np.maximum(d_cur[None] - dn, 0.0).sum(1) * valid                       # E (Eq. 5–6)
        angle = np.exp(-phi ** 2 / (2 * sigma ** 2))                                  # angle term
        # tropism: each new branch's angle γ from the vertical against the example's (mean, std)
        gam = np.degrees(np.abs(np.arctan2(dirs[..., 0], dirs[..., 1])))              # (2, L)
        trop = np.exp(-np.sum((gam - o_mean) ** 2, 0) / (2 * o_std ** 2)) if p.tropism else 1.0
        post = angle * trop * (gain / gain.sum() if gain.sum() > 0 else 1.0) * valid
        b = int(np.argmax(post))
        live.pop(k)
        for c in range(2):
            pos.append(ends[c, b].copy())
            par.append(i)
            if ll[c] >= min_len or len(live) < 2:     # short branches stop, but never the last tips
                live.append(len(pos) - 1)
        d_cur = np.minimum(d_cur, dn[b])
        total += need
    report(progress, "growing", 1.0)
    parents, xz, anchor = _subdivide(np.array(par), np.array(pos), region, n_seg, p.bend, rng)
    xz = pull_inside(xz, parents, region.polygon)
    return Grown2D(parents, xz, anchor, stopped)


def pull_inside(pos: np.ndarray, parents: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Nodes ``pos (N, 2)`` that the raster test let out of the exact ``polygon (M, 2)`` (a cell
    or two, where the outline turns sharply, e.g. a heart's notch) slid back toward their parent
    until inside (bisection; parents first, so the parent is already inside)."""
    import cv2
    c = np.asarray(polygon, np.float32).reshape(-1, 1, 2)

    def inside(q):
        return cv2.pointPolygonTest(c, (float(q[0]), float(q[1])), True) >= 0.0
    out = pos.copy()
    for n in np.flatnonzero(parents >= 0):
        if inside(out[n]):
            continue
        a, b = 0.0, 1.0                                   # a: inside (at the parent), b: outside
        for _ in range(20):
            m = 0.5 * (a + b)
            if inside(out[parents[n]] + m * (out[n] - out[parents[n]])):
                a = m
            else:
                b = m
        a = max(a, 0.05)                                  # never a zero-length bone
        out[n] = out[parents[n]] + a * (out[n] - out[parents[n]])
    return out


def _dirichlet(rng: np.random.Generator, alpha: np.ndarray) -> np.ndarray:
    z = rng.dirichlet(alpha)
    z = np.maximum(np.where(np.isfinite(z), z, 0.0), 1e-9)
    return z / z.sum()


def _subdivide(par: np.ndarray, pos: np.ndarray, region: Region2D, n_seg, bend: float,
               rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split every anchor edge into ``n_seg(length)`` bones, bent by a minimum-jerk bump of up to
    ``bend`` × length where the bent branch stays inside Ω'. Parents precede children."""
    from ..detail.shapes import minimum_jerk
    new_index = np.zeros(len(par), int)
    parents = [-1]
    out = [pos[0]]
    anchor = [True]
    for a in range(1, len(par)):                     # anchors were created parents-first
        p = par[a]
        A, B = pos[p], pos[a]
        L = float(np.linalg.norm(B - A))
        n = n_seg(L)
        if n > 1:
            tau = np.arange(1, n) / n
            s = minimum_jerk(tau)
            normal = np.array([-(B - A)[1], (B - A)[0]]) / max(L, 1e-12)
            off = bend * L * rng.uniform(-1.0, 1.0)
            mids = A[None] + (B - A)[None] * tau[:, None] + normal[None] * (off * 4 * s * (1 - s))[:, None]
            if not region.contains(mids).all():
                mids = A[None] + (B - A)[None] * tau[:, None]
        else:
            mids = np.zeros((0, 2))
        prev = new_index[p]
        for m in mids:
            out.append(m)
            parents.append(prev)
            anchor.append(False)
            prev = len(out) - 1
        out.append(B)
        parents.append(prev)
        anchor.append(True)
        new_index[a] = len(out) - 1
    return np.array(parents, np.int32), np.array(out, np.float64), np.array(anchor, bool)


def lift_grown(g: Grown2D, region: Region2D, conifer: bool, p: GrowParams,
               progress: ProgressFn | None = None, env: Envelope | None = None):
    """3D rest pose ``(N, 3)`` metres of the 2D tree by :func:`..reconstruct.lift.lift` on a raster of Ω'
    ``RASTER_HEIGHT_PX`` tall, depths then clipped into ``env``; returns (nodes, Lift)."""
    H = max(region.height(), float(g.pos[:, 1].max()), 1e-6)
    k = RASTER_HEIGHT_PX / H                                       # px per metre
    poly = np.asarray(region.polygon, np.float64)
    lo, hi = np.minimum(poly.min(0), g.pos.min(0)), np.maximum(poly.max(0), g.pos.max(0))
    bx, by = -lo[0] * k + 10.0, hi[1] * k + 10.0
    W, Hh = int(np.ceil((hi[0] - lo[0]) * k)) + 21, int(np.ceil(hi[1] * k)) + 21

    def to_px(xz):
        return np.stack([bx + xz[..., 0] * k, by - xz[..., 1] * k], -1)
    poly_px = to_px(poly)
    mask = polygon_to_mask(poly_px, W, Hh)
    mask[int(round(by)) + 1:] = False
    skel = Skeleton2D(g.parents, to_px(g.pos)[None].astype(np.float32), branching_level(g.parents), 24.0, "generated")
    lp = LiftParams(candidates=int(p.lift_candidates), attractors=int(p.lift_attractors), conifer=bool(conifer),
                    seed=int(p.seed))
    lifted = lift(skel, Outline(poly_px.astype(np.float32), mask), lp, progress)
    nodes = lifted.nodes / k                                       # plane frame px → metres
    nodes[:, [0, 2]] = g.pos                                       # exact 2D positions
    if env is not None:
        # the push keeps nodes inside the raster's envelope; where Ω's radius changes fast with
        # height (crown over trunk) a row of rounding can leave a node a little outside the true
        # one — pull its depth back to the surface
        lim = env.depth_limit(nodes)
        nodes[:, 1] = np.clip(nodes[:, 1], -lim, lim)
    return nodes, lifted


def species_radii(parents: np.ndarray, height: float, widths: tuple | None, tip: float | None = None,
                  exponent: float | None = None, fixed: np.ndarray | None = None) -> np.ndarray:
    """Pipe-model radii ``(N,)`` metres (``r_parent^e = Σ r_child^e``) of a tree ``height`` m
    tall. With the source's ``widths = (trunk, tip)`` (shares of the height): tips ``tip·H`` and
    the exponent that makes the trunk base ``trunk·H`` (n tips of one radius give a trunk of
    ``tip · n^(1/e)``, so ``e = ln n / ln(trunk / tip)``, kept in [1.5, 4]), then scaled so the
    trunk base is exactly ``trunk·H``. ``tip`` / ``exponent`` given override the fit. ``fixed (N,)``
    metres (nan: free): placed cuts' radii, kept, and the branches carrying them thickened to carry
    them (the tips as thick as without them: the fit is made on the tree as it is)."""
    if widths is None:
        tip_m, e = (0.0025 if tip is None else tip) * height, 2.0 if exponent is None else exponent
    else:
        trunk, tip_w = float(widths[0]), float(widths[1]) if tip is None else float(tip)
        n_tips = max(int(len(parents) - len(np.unique(parents[parents >= 0]))), 1)
        ratio = trunk / max(tip_w, 1e-12)
        e = (float(np.clip(np.log(n_tips) / np.log(ratio), 1.5, 4.0)) if ratio > 1 and n_tips > 1 else 2.0) \
            if exponent is None else float(exponent)
        tip_m = tip_w * height
        r = pipe_radii(parents, tip_m, e)
        k = trunk * height / float(r[0]) if exponent is None and tip is None and r[0] > 0 else 1.0  # trunk·H
        if fixed is None:
            return (r * k).astype(np.float32)
        tip_m *= k                                    # pipe radii scale with the tips'; the cuts' stay
    return pipe_radii(parents, tip_m, e, fixed).astype(np.float32)


#: a placed cut with less of its nodes inside the envelope is reported
CUT_INSIDE_WARN = 0.9


def _warn_cuts(infos: list[dict]) -> None:
    """A warning (the number and the fix) for each cut that sticks out of the envelope or whose
    displaced branches found no room to grow back."""
    import warnings
    for i in infos:
        if i["inside_share"] < CUT_INSIDE_WARN:
            warnings.warn(f"cut '{i['file']}': only {i['inside_share']:.0%} of its nodes are inside the envelope "
                          "where it was placed; put its base nearer the crown's middle, or let it fit (no point)",
                          RuntimeWarning, stacklevel=3)
        if i["regrown"] < i["taken_off"]:
            warnings.warn(f"cut '{i['file']}': {i['taken_off']} nodes made way for it and {i['regrown']} found room "
                          "to grow back; the tree has fewer branches than its budget", RuntimeWarning, stacklevel=3)


def with_twigs(tree: Tree3D, rest: np.ndarray, region: Region2D, params: TwigParams,
               bare: np.ndarray | None = None) -> Tree3D:
    """``tree`` with twigs (:func:`..detail.twigs.add_twigs`) laid out on its rest pose ``rest
    (N, 3)`` metres, whatever its first frame's sway (so the wind does not change them), inside
    the drawn outline ``region`` as well as the envelope, and riding on the tree's motion from rest;
    none on the tips ``bare (N,)`` marks (a placed cut's, which keeps its own)."""
    first = Tree3D(tree.parents, np.concatenate([rest[None], tree.nodes3d]).astype(np.float32), tree.radius,
                   tree.level, tree.fps, tree.name, tree.meta)
    out = add_twigs(first, params, inside=lambda pts: region.contains(pts[..., [0, 2]]), bare=bare)
    out.nodes3d = out.nodes3d[1:]
    return out


def grow_tree(model: SpeciesModel, envelope: Envelope, params: GrowParams | None = None,
              audio: str | os.PathLike | np.ndarray | None = None,
              progress: ProgressFn | None = None) -> Tree3D:
    """A new animated tree (metres; node 0 the trunk base at the origin) like ``model`` inside
    ``envelope`` (module docstring). ``audio``: a WAV path or an envelope ``(F,)`` (mean 1) that
    modulates the sway. ``meta`` has "species", "seed", "envelope" (z/centre/radius and the 2D
    polygon, metres), "generated", "wind", "stopped", "conifer", "mu_deg", "height_px",
    "metres_per_px", "leaf_density". Cancellable through ``progress``; deterministic per seed."""
    p = params or GrowParams()
    check_params(p)
    env = envelope
    env_h = float(np.max(env.z)) if len(env.z) else 0.0
    if not env_h > 0 or not np.max(env.radius) > 0:
        raise InputError("the envelope is empty (no height or width); pick a shape, an image or a curve")
    if p.height_m is not None and abs(p.height_m - env_h) > 1e-9 * env_h:
        env = scale_envelope(env, p.height_m / env_h)
    fps = float(p.fps or model.fps)
    n_frames = int(p.n_frames)
    period_s = None
    if p.loop_s > 0 and audio is None:             # a recording's gusts do not repeat: blended later
        loop_frames = max(int(round(p.loop_s * fps)), 2)
        n_frames, period_s = loop_frames + 1, loop_frames / fps
    conifer = model.conifer if p.conifer is None else bool(p.conifer)
    gains = None
    if audio is not None:
        a = audio_envelope(audio, fps, n_frames) if isinstance(audio, (str, os.PathLike)) else audio
        gains = gain_curve(n_frames, p.wind, a)
    else:
        gains = gain_curve(n_frames, p.wind)
    ss = np.random.SeedSequence([int(p.seed) & 0xFFFFFFFF, 0x7EE])
    rng_grow, rng_sway = (np.random.default_rng(s) for s in ss.spawn(2))
    variation = holton = None
    leaves_info = model.leaves
    if p.envelope_variation > 0:                   # its own crown and leaf colour (crown_space)
        rng_var = np.random.default_rng([int(p.seed) & 0xFFFFFFFF, 0xE17])
        space = contour_space(model.contours, library_contours())
        env, variation = varied_envelope(env, space, float(p.envelope_variation), rng_var)
        leaves_info, variation["leaf_colour"] = varied_leaf_colour(model.leaves, float(p.envelope_variation), rng_var)
    region = region_of(env)
    report(progress, "growing", 0.0)
    palm = model.palm if model.form == "palm" else None
    if palm and p.cuts:
        raise InputError(f"tree-cuts go in branching trees; species '{model.name}' grows palms (fronds on a stem): "
                         "drop the cuts or pick another species")
    fixed, cut_info, cuts = None, None, []
    if palm:
        from .palm import grow_palm
        par, rest = grow_palm(palm, env, rng_grow)
        g = Grown2D(par, rest[:, [0, 2]], np.ones(len(par), bool), "palm")
        mu = math.radians(model.mu_deg)
        report(progress, "growing", 0.85)
    else:
        cuts = [(load_cut(c.path), None if c.at is None else np.asarray(c.at, np.float64)) for c in p.cuts]
        p_grow = replace(p, node_budget=max(int(p.node_budget) - sum(c.n_bones for c, _ in cuts), 8)) if cuts else p
        g = grow_2d(model, region, p_grow, rng_grow, sub_progress(progress, 0.0, 0.4))
        rest, lifted = lift_grown(g, region, conifer, p, sub_progress(progress, 0.4, 0.85), env)
        if p.allometry and not conifer:            # Holton's angles at the forks (seed 001 §4.4); a
            # conifer's whorls off its leader are no forks of two (measured: turning them rounds its cone)
            r_h = species_radii(g.parents, float(max(rest[:, 2].max(), 1e-6)), model.widths, p.tip_radius,
                                p.pipe_exponent)
            cell = region.height() / RASTER_ROWS        # inside as the growth keeps its nodes (2D and Ω's depth)
            rest, holton = holton_pose(g.parents, rest, g.anchor, r_h,
                                       inside=lambda q: region.contains(q[:, [0, 2]]) & env.contains(q, tol=cell))
        mu = float(lifted.mu)
        if cuts:                                   # the tree-cuts, the rest grown around them
            cell = region.height() / RASTER_ROWS
            placed = place_cuts(g.parents, rest, lambda par, pos: species_radii(
                par, float(max(pos[:, 2].max(), 1e-6)), model.widths, p.tip_radius, p.pipe_exponent), cuts,
                inside=lambda q: region.contains(q[:, [0, 2]]) & env.contains(q, tol=cell),
                rng=np.random.default_rng([int(p.seed) & 0xFFFFFFFF, 0xC07]))
            parents, rest, fixed = placed.parents, placed.rest, placed.cut_radius
            cut_info = [{"file": os.path.basename(c.path), **i} for c, i in zip(p.cuts, placed.info["cuts"])]
            _warn_cuts(cut_info)
    report(progress, "animating", 0.85)
    if fixed is None:
        parents = g.parents
    phase = None if p.tree_phase is None else np.asarray(p.tree_phase, float)
    rot = sample_rotations(model, parents, rest, n_frames, fps, rng_sway, p.time_offset_s, phase, period_s)
    # the species' own sway (wind 1) sways as far as its source did and stays inside the envelope;
    # the wind then scales it (×2 is ×2)
    rot = rot * match_excursion(parents, rest, rot, model.sway_excursion)
    unit, sway_scale = contain_sway(parents, rest, rot, region)
    if np.all(gains == 1.0):
        nodes3d = unit
    else:
        nodes3d = forward_kinematics(parents, rest, rot * (sway_scale * gains[:, None, None]))
    report(progress, "animating", 1.0)
    H = float(max(rest[:, 2].max(), 1e-6))
    radius = species_radii(parents, H, model.widths, p.tip_radius, p.pipe_exponent, fixed)
    k = RASTER_HEIGHT_PX / max(region.height(), float(g.pos[:, 1].max()), 1e-6)
    meta: TreeMeta = {"species": model.name, "seed": int(p.seed), "generated": True, "envelope": envelope_meta(env),
            "wind": float(p.wind), "audio": os.fspath(audio) if isinstance(audio, (str, os.PathLike)) else
            (None if audio is None else "envelope"), "stopped": g.stopped, "conifer": bool(conifer),
            "form": model.form if p.conifer is None else ("conifer" if conifer else "broadleaf"),
            "mu_deg": float(np.degrees(mu)), "height_px": float(H * k), "metres_per_px": float(1.0 / k),
            "leaf_density": float(p.leaf_density), "node_budget": int(p.node_budget),
            "time_offset_s": float(p.time_offset_s), "sway_scale": float(sway_scale),
            "mesh": {"curliness": float(p.curliness), "bark": str(p.bark), "seed": int(p.seed),
                     "forks": str(p.forks), "relief_cm": float(p.relief_cm)}}
    if period_s is not None:
        meta["periodic"] = {"frames": int(n_frames - 1), "seconds": float(period_s)}
    if variation is not None:
        meta["envelope_variation"] = variation
    meta["allometry"] = allometry_report(parents, rest, radius, model.mu_deg)
    if holton is not None:
        meta["allometry"]["holton_turns"] = holton
    if cut_info is not None:
        meta["cuts"] = cut_info
    tree = Tree3D(parents.astype(np.int32), nodes3d.astype(np.float32), radius,
                  branching_level(parents).astype(np.int32), fps, p.name or f"{model.name}_{int(p.seed)}", meta)
    if not palm and p.twig_depth > 0:
        tree = with_twigs(tree, rest, region, TwigParams(depth=int(p.twig_depth), seed=int(p.seed)),
                          None if fixed is None else np.isfinite(fixed))
    if p.leaf_density > 0 and leaves_info is not None:
        from ..detail.grown_leaves import grow_leaves
        tree.leaves = grow_leaves(tree, leaves_info, p.leaf_density, int(p.seed), envelope=env)
    return tree
