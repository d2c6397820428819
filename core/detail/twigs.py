"""Twigs by self-similarity (paper §3.3: "small branches and twigs are added using self-similarity").

Below the finest reconstructed level — at every tip of the tree — :func:`add_twigs` grows new
branches by copying the tree's **own bifurcations**:

* A *bifurcation template* is measured at every fork ``f`` (a node with two or more children that
  has a parent). Its *parent* is the chain of bones that ends at ``f`` (from the previous fork or
  the root): direction ``e`` = the last bone's direction into ``f``, length ``L`` = the chain's
  chord. Each child chain (from ``f`` to the next fork or tip) gives one child vector ``c``
  (its chord), stored as ``θ = ∠(c, e)``, ``ρ = |c| / L`` and an azimuth ``φ`` about ``e``
  measured from the world-up direction projected perpendicular to ``e`` (so "side branches grow
  upward" survives the copy).
* Generation 1 attaches one randomly chosen template at every tip of the reconstructed tree (parent
  direction = the tip bone's direction, length = the tip chain's chord). Each twig is a single
  bone ``c = L ρ (cos θ e + sin θ (cos(φ + ψ) u + sin(φ + ψ) w))`` with ``u`` the up-reference
  perpendicular to ``e``, ``w = e × u`` and a random roll ``ψ`` uniform in ±:data:`ROLL_JITTER`.
  Generation ``g + 1`` does the same on every twig of generation ``g`` (its own bone is the
  parent), up to ``depth`` generations: the copy of a ``depth``-deep subtree whose angle and
  length ratios are those of the tree's own forks.
* Inside the envelope at frame 0: every twig is tested at 4 points along it; one that leaves the
  envelope is shrunk (factors :data:`SHRINK`) and dropped (with everything it would carry) when
  even the shortest one leaves it or is shorter than ``min_length``. Without an envelope in
  ``tree.meta`` nothing is rejected.
* Radii: a template's children share the parent tip's cross-section by the pipe model with area ∝
  ρ², ``r_k = r_tip ρ_k / sqrt(Σ_j ρ_j²)`` — always below the tip radius for forks of ≥ 2 children.

Motion (documented choice): a twig — the whole subtree grown from one tip node ``a`` of the
reconstructed tree — is a **rigid shape** riding on the world rotation ``Q(t)`` of the bone that
ends at ``a`` (the *driver*), delayed by ``lag_frames`` and attenuated toward rest:

    ``Q_twig(t) = slerp(Q(t − lag), I, attenuation)``,  ``x_j(t) = x_a(t) + Q_twig(t) (x_j(0) − x_a(0))``

with ``Q(t < lag) = Q(0) = I`` (frame 0 is the rest pose). The twig's root stays glued to the tip it
grows from (bones stay connected); only its orientation lags (inertia) and swings by less
(stiffness): for small angles its swing is ``(1 − attenuation)`` times the driver's swing
``lag`` frames earlier. Bone lengths are exact at every frame.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .. import bones, rotations
from ..envelope import envelope_from_meta
from ..errors import InputError
from ..params import check, param
from ..progress import ProgressFn, report
from ..topology import chains
from ..tree3d import Tree3D, plane_to_image

#: shrink factors tried, in order, for a twig that leaves the envelope
SHRINK = (1.0, 0.8, 0.6, 0.4)
#: random roll of a copied template about its parent direction, ± radians
ROLL_JITTER = math.pi / 4
#: fractions along a twig where the envelope is tested
PROBES = (0.25, 0.5, 0.75, 1.0)
#: template used when the tree has no fork to copy: two children, θ = 35°, ρ = 0.7 and 0.6
FALLBACK = np.array([[math.radians(15.0), 0.0, 0.7], [math.radians(40.0), math.pi, 0.6]])


@dataclass
class TwigParams:
    """``depth`` generations of twigs (0 = off: the tree is returned unchanged); ``seed`` for the
    template choice and roll; ``lag_frames`` (frames, ≥ 0) and ``attenuation`` (0 = follow the
    driver's rotation fully, 1 = stay at rest) of the twigs' motion; at most ``max_nodes`` twig
    nodes in all; twigs shorter than ``min_length`` × the tree's height are dropped."""

    depth: int = param(2, 0, 6, what="twig depth", fix="0: no twigs")
    seed: int = 0
    lag_frames: int = 2
    attenuation: float = 0.25
    max_nodes: int = 5000
    min_length: float = 1e-3


def check_twig_params(p: TwigParams) -> None:
    """Raise :class:`InputError` for a twig setting out of range."""
    check(p)
    if p.lag_frames < 0 or not 0.0 <= p.attenuation <= 1.0:
        raise InputError(f"twig lag {p.lag_frames} frames / attenuation {p.attenuation} out of range; "
                         "use lag ≥ 0 and attenuation in 0..1")


@dataclass
class Templates:
    """Bifurcation templates measured on a tree: ``theta, phi, rho (K,)`` per child (radians,
    radians, ratio) and ``start (T + 1,)`` offsets: template ``t`` is children ``start[t]:start[t+1]``;
    ``fork (T,)`` the fork node of each template (−1 for the fallback)."""

    theta: np.ndarray
    phi: np.ndarray
    rho: np.ndarray
    start: np.ndarray
    fork: np.ndarray

    @property
    def n(self) -> int:
        return len(self.start) - 1

    @property
    def count(self) -> np.ndarray:
        return np.diff(self.start)


# ----------------------------------------------------------------------------- geometry helpers

def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.linalg.norm(v, axis=-1)
    return v / np.maximum(n, 1e-12)[..., None], n


def _frame(e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit ``u, w (M, 3)`` perpendicular to unit ``e (M, 3)``: ``u`` = world up (+z) made
    perpendicular to ``e`` (world +x where ``e`` is vertical), ``w = e × u``."""
    up = np.broadcast_to(np.array([0.0, 0.0, 1.0]), e.shape)
    u = up - np.sum(up * e, axis=-1, keepdims=True) * e
    u, n = _unit(u)
    vertical = n < 1e-6
    if vertical.any():
        ev = e[vertical]
        u[vertical] = _unit(np.array([1.0, 0.0, 0.0]) - ev[:, :1] * ev)[0]
    return u, np.cross(e, u)


def _compose(e: np.ndarray, length: np.ndarray, theta: np.ndarray, phi: np.ndarray,
             rho: np.ndarray) -> np.ndarray:
    """Child vectors ``(M, 3)`` = ``length ρ (cos θ e + sin θ (cos φ u + sin φ w))``."""
    u, w = _frame(e)
    d = (np.cos(theta)[:, None] * e
         + np.sin(theta)[:, None] * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * w))
    return (length * rho)[:, None] * d


def measure_templates(parents: np.ndarray, pos: np.ndarray) -> Templates:
    """Bifurcation templates of a tree: ``parents (N,)``, rest positions ``pos (N, 3)`` metres
    (see the module docstring). Falls back to :data:`FALLBACK` when the tree has no usable fork."""
    parents = np.asarray(parents)
    pos = np.asarray(pos, np.float64)
    N = len(parents)
    n_child = np.bincount(parents[parents >= 0], minlength=N)
    roots = parents < 0
    forks = (n_child >= 2) & ~roots
    anchors = roots | (n_child != 1)            # roots, forks and tips
    ch = chains(parents, pos, anchors)
    # child chains: every non-root anchor whose chain starts at a fork
    ends = np.flatnonzero(anchors & ~roots)
    starts = ch.up[ends]
    keep = (starts >= 0) & forks[np.maximum(starts, 0)]
    ends, starts = ends[keep], starts[keep]
    if len(ends) == 0:
        return _fallback()
    order = np.argsort(starts, kind="stable")
    ends, starts = ends[order], starts[order]
    e, _ = _unit(pos[starts] - pos[parents[starts]])                         # last bone into the fork
    up_anchor = ch.up[starts]
    L = np.linalg.norm(pos[starts] - pos[np.maximum(up_anchor, 0)], axis=1)
    L = np.maximum(L, np.linalg.norm(pos[starts] - pos[parents[starts]], axis=1))
    c = pos[ends] - pos[starts]
    cu, clen = _unit(c)
    theta = np.arccos(np.clip(np.sum(cu * e, axis=1), -1.0, 1.0))
    u, w = _frame(e)
    phi = np.arctan2(np.sum(cu * w, axis=1), np.sum(cu * u, axis=1))
    rho = clen / L
    ok = (clen > 0) & (L > 0)
    if not ok.all():
        ends, starts, theta, phi, rho = ends[ok], starts[ok], theta[ok], phi[ok], rho[ok]
    fork_ids, first, counts = np.unique(starts, return_index=True, return_counts=True)
    good = counts >= 2                          # a fork with fewer usable children is no template
    if not good.any():
        return _fallback()
    sel = np.concatenate([np.arange(f, f + k) for f, k in zip(first[good], counts[good])])
    start = np.concatenate([[0], np.cumsum(counts[good])])
    return Templates(theta[sel], phi[sel], rho[sel], start, fork_ids[good])


def _fallback() -> Templates:
    return Templates(FALLBACK[:, 0].copy(), FALLBACK[:, 1].copy(), FALLBACK[:, 2].copy(),
                     np.array([0, len(FALLBACK)]), np.array([-1]))


# ----------------------------------------------------------------------------- rotations

def slerp_to_rest(q: np.ndarray, attenuation: float) -> np.ndarray:
    """``slerp(q, I, a)`` for unit quaternions ``q (..., 4)`` (w, x, y, z): the same axis, the angle
    times ``1 − a`` (the short way round)."""
    q = np.where(q[..., :1] < 0, -q, q)
    w = np.clip(q[..., 0], -1.0, 1.0)
    half = np.arccos(w)                                        # θ/2
    s = np.sin(half)
    axis = np.where(s[..., None] > 1e-12, q[..., 1:] / np.maximum(s, 1e-12)[..., None], 0.0)
    h2 = (1.0 - attenuation) * half
    return np.concatenate([np.cos(h2)[..., None], np.sin(h2)[..., None] * axis], axis=-1)


def twig_rotations(driver_q: np.ndarray, lag: int, attenuation: float, period: int | None = None) -> np.ndarray:
    """``Q_twig(t) = slerp(Q(t − lag), I, attenuation)`` for ``driver_q (F, M, 4)``; frames
    before ``lag`` use frame 0 (the rest), or with ``period`` (a motion that repeats after that
    many frames, a generated loop) the frames one period later: the twigs repeat too."""
    F = len(driver_q)
    src = np.arange(F) - int(lag)
    src = np.mod(src, int(period)) if period else np.clip(src, 0, F - 1)
    return slerp_to_rest(driver_q[src], attenuation)


# ----------------------------------------------------------------------------- growth

def add_twigs(tree: Tree3D, params: TwigParams | None = None,
              progress: ProgressFn | None = None, tree_px: np.ndarray | None = None,
              inside: Callable[[np.ndarray], np.ndarray] | None = None,
              bare: np.ndarray | None = None) -> Tree3D:
    """A new :class:`Tree3D` with twigs appended (see the module docstring).

    The original nodes keep their indices (so bones ``B{child:03d}`` of the reconstructed tree keep
    their names); twig nodes follow, parents before children. ``radius`` and ``level`` (parent + 1)
    are extended and ``nodes3d (F, N', 3)`` holds every frame. ``meta["twigs"]`` records
    ``first_node`` (index of the first twig node), ``nodes_added``, ``per_generation``, ``rejected``,
    ``shrunk``, ``templates``, ``depth``, ``seed``, ``lag_frames``, ``attenuation``. With
    ``params.depth == 0`` the tree is returned unchanged (the same object). With ``tree_px (H, W)``
    (frame 1's tree pixels, :func:`.branch_fit.tree_map`) and ``meta["base_px"]`` /
    ``meta["metres_per_px"]``, a twig must also lie over the tree in frame 1 (see
    :func:`on_tree_pixels`): where the video shows sky, it shows no twig. ``inside(pts (..., 3)
    metres) -> (...) bool`` is one more test every twig must pass (a generated tree's drawn
    outline, which the envelope's surface of revolution only bounds). ``bare (N,)`` bool: tips that
    grow no twigs (a placed tree-cut's: it stays as it was saved)."""
    p = params or TwigParams()
    if p.depth <= 0:
        return tree
    check_twig_params(p)
    parents = np.asarray(tree.parents, np.int64)
    nodes = np.asarray(tree.nodes3d, np.float64)
    rest = nodes[0]
    N = len(parents)
    env = envelope_from_meta(tree.meta)
    seen = on_tree_pixels(tree_px, tree.meta) if tree_px is not None else None
    if inside is not None:
        seen = inside if seen is None else (lambda pts, a=seen, b=inside: a(pts) & b(pts))
    height = max(float(np.ptp(rest, axis=0).max()), 1e-6)
    min_len = p.min_length * height
    rng = np.random.default_rng(p.seed)
    tpl = measure_templates(parents, rest)
    sum_rho2 = np.add.reduceat(tpl.rho ** 2, tpl.start[:-1])                  # (T,)

    # generation-1 frontier: the tips of the reconstructed tree
    n_child = np.bincount(parents[parents >= 0], minlength=N)
    tips = np.flatnonzero((n_child == 0) & (parents >= 0) & (True if bare is None else ~np.asarray(bare, bool)))
    anchors = (parents < 0) | (n_child != 1)
    ch = chains(parents, rest, anchors)
    f_node = tips
    f_dir, last_len = _unit(rest[tips] - rest[parents[tips]])
    f_len = np.maximum(np.linalg.norm(rest[tips] - rest[np.maximum(ch.up[tips], 0)], axis=1), last_len)
    f_rad = np.asarray(tree.radius, np.float64)[tips]
    f_lvl = np.asarray(tree.level, np.int64)[tips]
    f_root = tips                                   # the reconstructed tip each twig grows from

    new_parent: list[np.ndarray] = []
    new_pos: list[np.ndarray] = []
    new_rad: list[np.ndarray] = []
    new_lvl: list[np.ndarray] = []
    new_root: list[np.ndarray] = []
    per_gen, rejected, shrunk = [], 0, 0
    n_next = N
    budget = int(p.max_nodes)
    for g in range(int(p.depth)):
        if len(f_node) == 0 or budget <= 0:
            break
        t = rng.integers(0, tpl.n, len(f_node))
        k = tpl.count[t]
        item = np.repeat(np.arange(len(f_node)), k)                            # child -> frontier item
        child = tpl.start[t][item] + (np.arange(len(item)) - np.repeat(np.cumsum(k) - k, k))
        roll = rng.uniform(-ROLL_JITTER, ROLL_JITTER, len(f_node))[item]
        vec = _compose(f_dir[item], f_len[item], tpl.theta[child], tpl.phi[child] + roll, tpl.rho[child])
        base = _rest_of(f_node[item], rest, new_pos)
        scale = _fit(base, vec, env, min_len, seen)
        ok = scale > 0
        rejected += int((~ok).sum())
        shrunk += int((ok & (scale < 1.0)).sum())
        idx = np.flatnonzero(ok)
        if len(idx) > budget:
            idx = np.sort(rng.choice(idx, budget, replace=False))
        vec = vec[idx] * scale[idx, None]
        rad = f_rad[item][idx] * tpl.rho[child][idx] / np.sqrt(sum_rho2[t[item][idx]])
        m = len(idx)
        new_parent.append(f_node[item][idx])
        new_pos.append(base[idx] + vec)
        new_rad.append(rad)
        new_lvl.append(f_lvl[item][idx] + 1)
        new_root.append(f_root[item][idx])
        per_gen.append(m)
        f_node = n_next + np.arange(m)
        f_dir, f_len = _unit(vec)
        f_rad, f_lvl, f_root = rad, f_lvl[item][idx] + 1, f_root[item][idx]
        n_next += m
        budget -= m
        report(progress, "twigs", 0.8 * (g + 1) / p.depth)

    added = n_next - N
    meta = tree.meta.copy()
    meta["twigs"] = {"first_node": int(N), "nodes_added": int(added), "per_generation": per_gen,
                     "rejected": rejected, "shrunk": shrunk, "templates": int(tpl.n), "depth": int(p.depth),
                     "seed": int(p.seed), "lag_frames": int(p.lag_frames), "attenuation": float(p.attenuation)}
    if added == 0:
        return _carry(tree, Tree3D(tree.parents.copy(), tree.nodes3d.copy(), tree.radius.copy(),
                                   tree.level.copy(), tree.fps, tree.name, meta))
    t_parent = np.concatenate(new_parent)
    t_pos = np.concatenate(new_pos)
    t_root = np.concatenate(new_root)
    out_nodes = np.empty((len(nodes), n_next, 3), np.float64)
    out_nodes[:, :N] = nodes
    period = (tree.meta.get("periodic") or {}).get("frames")      # a generated loop: twigs loop too
    out_nodes[:, N:] = animate(nodes, parents, t_root, t_pos, p.lag_frames, p.attenuation, period)
    report(progress, "twigs", 1.0)
    return _carry(tree, Tree3D(
        np.concatenate([parents, t_parent]).astype(np.int32), out_nodes.astype(np.float32),
        np.concatenate([np.asarray(tree.radius, np.float64), np.concatenate(new_rad)]).astype(np.float32),
        np.concatenate([np.asarray(tree.level, np.int64), np.concatenate(new_lvl)]).astype(np.int32),
        tree.fps, tree.name, meta))


def without_twigs(tree: Tree3D) -> Tree3D:
    """The branches of ``tree`` without the twigs :func:`add_twigs` copied onto them (appended
    after ``meta["twigs"]["first_node"]``), leaves kept: what a species is fitted from (twigs
    would halve the branch scale it learns and its trees would stop growing at 60 % of Ω')."""
    first = (tree.meta.get("twigs") or {}).get("first_node")
    if not first or first >= tree.n_nodes:
        return tree
    n = int(first)
    return replace(tree, parents=tree.parents[:n], nodes3d=tree.nodes3d[:, :n],
                   radius=tree.radius[:n], level=tree.level[:n])


def _carry(src: Tree3D, out: Tree3D) -> Tree3D:
    """Keep what else ``src`` carries (leaf clusters sit on original nodes, whose indices stay)."""
    if getattr(src, "leaves", None) is not None:
        out.leaves = src.leaves
    out.times = src.times
    return out


def _rest_of(idx: np.ndarray, rest: np.ndarray, new_pos: list) -> np.ndarray:
    """Rest positions ``(M, 3)`` of nodes ``idx`` among the original ``rest (N, 3)`` and the twig
    positions appended so far (``new_pos``: list of ``(m, 3)`` arrays in node order after N)."""
    allpos = np.concatenate([rest] + new_pos) if new_pos else rest
    return allpos[idx]


#: a twig over frame 1's tree pixels may stray this far (px) from them (blur, 1 px twigs)
TREE_PX_MARGIN = 2


def on_tree_pixels(tree_px: np.ndarray, meta: Mapping[str, Any]):
    """``seen(pts (..., 3) metres) -> (...) bool``: the rest-pose point, seen like frame 1 (x right,
    z up from the trunk base ``meta["base_px"]``, ``meta["metres_per_px"]``), falls on the tree's
    pixels ``tree_px (H, W)`` grown by :data:`TREE_PX_MARGIN`; None without the placement."""
    import cv2
    if "base_px" not in meta or "metres_per_px" not in meta:
        return None
    k = 2 * TREE_PX_MARGIN + 1
    grown = cv2.dilate(np.asarray(tree_px, np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))) > 0
    base = np.asarray(meta["base_px"], np.float64)
    m = float(meta["metres_per_px"])
    h, w = grown.shape

    def seen(pts: np.ndarray) -> np.ndarray:
        xy = np.round(plane_to_image(pts / m, base)).astype(int)
        x, y = xy[..., 0], xy[..., 1]
        ok = (x >= 0) & (x < w) & (y >= 0) & (y < h)
        out = np.zeros(x.shape, bool)
        out[ok] = grown[y[ok], x[ok]]
        return out
    return seen


def _fit(base: np.ndarray, vec: np.ndarray, env, min_len: float, seen=None) -> np.ndarray:
    """Largest factor of :data:`SHRINK` keeping the twig ``base → base + s·vec`` inside the
    envelope (and, with ``seen``, over the tree's pixels) at all :data:`PROBES` and at least
    ``min_len`` long; 0 if none. ``(M,)``."""
    length = np.linalg.norm(vec, axis=1)
    shrink = np.asarray(SHRINK)
    f = shrink[None, :, None] * np.asarray(PROBES)[None, None, :]                   # (1, S, P)
    pts = base[:, None, None] + f[..., None] * vec[:, None, None]                  # (M, S, P, 3)
    inside = np.ones((len(vec), len(shrink)), bool)
    if env is not None:
        inside &= env.contains(pts, tol=0.0).all(axis=2)
    if seen is not None:
        inside &= seen(pts).all(axis=2)
    inside &= length[:, None] * shrink[None] >= min_len
    first = np.argmax(inside, axis=1)
    return np.where(inside.any(axis=1), shrink[first], 0.0)


def animate(nodes: np.ndarray, parents: np.ndarray, twig_root: np.ndarray, twig_rest: np.ndarray,
            lag: int, attenuation: float, period: int | None = None) -> np.ndarray:
    """Positions ``(F, M, 3)`` of twig nodes: ``x_j(t) = x_a(t) + Q_twig(t) (x_j(0) − x_a(0))`` with
    ``a = twig_root (M,)`` (a tip of the reconstructed tree ``parents (N,)``, ``nodes (F, N, 3)``),
    ``twig_rest (M, 3)`` and ``Q_twig`` from :func:`twig_rotations` of the bone ending at ``a``."""
    q = bones.world_rotations(parents, nodes)                                    # (F, B, 4)
    bone_of_node = np.full(len(parents), -1, np.int64)
    edges = bones.bone_edges(parents)
    bone_of_node[edges[:, 1]] = np.arange(len(edges))
    roots, inverse = np.unique(twig_root, return_inverse=True)
    qt = twig_rotations(q[:, bone_of_node[roots]], lag, attenuation, period)  # (F, R, 4)
    offset = twig_rest - nodes[0, twig_root]                                  # (M, 3)
    return nodes[:, twig_root] + rotations.quat_rotate(qt[:, inverse], offset[None])
