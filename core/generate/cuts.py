"""Placing tree-cuts (seed 001 §3 and its editing operator): a new tree that must contain cuts
(:class:`~..tree_cut.TreeCut`, parts of other trees kept in files) grows the rest around them.

**Placing** a cut in a grown tree (:func:`place_cut`), metres, the tree's rest pose:

1. its base goes on a node ``A`` of the tree: the node nearest the point the user gave (Blender's
   3D cursor in the tree's frame), else, "where its base fits", the best of up to
   :data:`CANDIDATES` nodes whose radius is nearest the cut's base radius by the score below;
2. it is turned rigidly (no scale): ``R = R_ψ(d_A) · R(u → d_A)``, its ``parent_dir`` ``u`` onto
   ``A``'s own bone ``d_A`` (the root's: up), then about that bone by the roll ψ of
   :data:`ROLLS` that scores best:

       score = inside share − collision share − damage − |ln(r_A / r_base)|   (the last only when fitting)

   (inside: the cut's nodes the envelope holds; collision: the points along the cut's bones
   (every quarter) farther than the clearance from its base that have a tree node within the
   clearance; damage: the largest share
   of the tree carried by one such node, ``A``'s ancestors spared — a cut that would take the
   crown off with the trunk above it scores low);
3. every tree branch whose bone (its middle or its tail) comes closer than the clearance to a cut
   bone is taken off with all it carries (``A`` and its ancestors stay);
4. as many nodes as were taken off grow back from the stumps and the tree's tips by space
   colonization (:mod:`.colonize`: step the tree's median bone, kill half of it) toward random
   points of the envelope twice the clearance from the cut, each step keeping the clearance.

The clearance is ``max(CLEAR_RADII · median cut radius, CLEAR_BONE · median tree bone)``. Radii then
follow the pipe model with the cut's kept (:func:`..tree3d.pipe_radii` ``fixed``): the branches
that carry a cut thicken to carry it.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..rotations import quat_to_matrix, rodrigues, swing
from ..topology import subtree, subtree_sizes, topological_order, without_nodes
from ..tree_cut import UP, TreeCut, bone_lengths

#: rolls ψ tried about the parent bone (evenly over a turn)
ROLLS = 24
#: nodes tried as the base when the generator places a cut
CANDIDATES = 48
#: the clearance: this many of the cut's median radius ...
CLEAR_RADII = 2.5
#: ... or this share of the tree's median bone, whichever is more
CLEAR_BONE = 0.5
#: tree nodes looked at round each cut node when scoring a place (the damage term)
NEAR_K = 8
#: :func:`place_cuts` numbers cut k's node i ``CUT_IDS · k + i``
CUT_IDS = 1_000_000


# ----------------------------------------------------------------------------- geometry

def segment_distances(pts: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance ``(S, P)`` from points ``pts (P, D)`` to segments ``a → b (S, D)`` (any D; the
    growth's 2D attractors use it too)."""
    ab = b - a
    ap = pts[None] - a[:, None]                                                  # (S, P, D)
    t = np.clip(np.einsum("spd,sd->sp", ap, ab) / np.maximum(np.sum(ab * ab, 1), 1e-18)[:, None], 0, 1)
    d = ap - t[..., None] * ab[:, None]
    return np.sqrt(np.sum(d * d, -1))


def segment_distance(pts: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(P,)`` metres from each of ``pts (P, 3)`` to the nearest of the segments ``a → b (S, 3)``."""
    if len(a) == 0:
        return np.full(len(pts), np.inf)
    return segment_distances(pts, a, b).min(axis=0)


def carriers(parents: np.ndarray, marked: np.ndarray) -> np.ndarray:
    """``(N,)`` bool: the ``marked`` nodes and every node on their way to the root."""
    out = np.asarray(marked, bool).copy()
    for n in topological_order(parents)[::-1]:          # leaves first
        if out[n] and parents[n] >= 0:
            out[parents[n]] = True
    return out


def ancestors(parents: np.ndarray, node: int) -> np.ndarray:
    """``(N,)`` bool: ``node`` and every node on its way to the root."""
    mask = np.zeros(len(parents), bool)
    n = int(node)
    while n >= 0:
        mask[n] = True
        n = int(parents[n])
    return mask


# ----------------------------------------------------------------------------- placing

@dataclass
class CutSpec:
    """A cut to place: ``path`` of its file, ``at (3,)`` metres in the tree's frame where its base
    goes (None: where it fits)."""

    path: str
    at: tuple[float, float, float] | None = None


def parse_cut_spec(text: str) -> CutSpec:
    """``FILE`` or ``FILE@X,Y,Z`` (metres from the tree's base) → :class:`CutSpec`."""
    path, sep, where = str(text).rpartition("@") if "@" in str(text) else (str(text), "", "")
    if not sep:
        return CutSpec(path)
    try:
        xyz = tuple(float(v) for v in where.split(","))
    except ValueError:
        xyz = ()
    if len(xyz) != 3 or not all(math.isfinite(v) for v in xyz):
        raise InputError(f"--cut '{text}': after @ give the base's place as X,Y,Z metres from the tree's base, "
                         "e.g. branch.npz@0.5,0,4")
    return CutSpec(path, (xyz[0], xyz[1], xyz[2]))


@dataclass
class Placed:
    """A tree with a cut in it: ``parents (N,)``, ``rest (N, 3)`` metres, ``cut (N,)`` int the
    index of the node in its cut (-1: not a cut's node; a cut's base is the tree's node, not the
    cut's), ``cut_radius (N,)`` metres the cut's radii (nan elsewhere), ``info`` what
    ``meta["cuts"]`` records; ``kept (K,)`` the old index of the tree's nodes kept (the first K, in
    their order)."""

    parents: np.ndarray
    rest: np.ndarray
    cut: np.ndarray
    cut_radius: np.ndarray
    kept: np.ndarray
    info: dict


def _candidates(parents: np.ndarray, radius: np.ndarray, frozen: np.ndarray, r_base: float,
                at: np.ndarray | None, rest: np.ndarray) -> np.ndarray:
    free = np.flatnonzero(~frozen)
    if at is not None:
        return free[[int(np.argmin(np.linalg.norm(rest[free] - at, axis=1)))]]
    gap = np.abs(np.log(np.maximum(radius[free], 1e-9) / max(r_base, 1e-9)))
    return free[np.argsort(gap, kind="stable")[:CANDIDATES]]


def place_cut(parents: np.ndarray, rest: np.ndarray, radius: np.ndarray, cut: TreeCut,
              at: np.ndarray | None = None, inside: Callable[[np.ndarray], np.ndarray] | None = None,
              frozen: np.ndarray | None = None, rng: np.random.Generator | None = None) -> Placed:
    """Put ``cut`` into the tree ``parents (N,)``, ``rest (N, 3)`` metres with radii ``radius (N,)``
    metres (the module docstring's steps 1–4). ``at (3,)`` metres: the base goes on the node nearest
    it; None: where it fits. ``inside (P, 3) → (P,)`` bool: the envelope (None: everywhere).
    ``frozen (N,)``: nodes of cuts placed before (never a base, never taken off). Deterministic per ``rng``."""
    parents = np.asarray(parents, np.int64)
    rest = np.asarray(rest, np.float64)
    radius = np.asarray(radius, np.float64)
    N = len(parents)
    frozen = np.zeros(N, bool) if frozen is None else np.asarray(frozen, bool)
    rng = rng or np.random.default_rng(0)
    inside = inside or (lambda q: np.ones(len(q), bool))
    from scipy.spatial import cKDTree

    tree_bone = bone_lengths(parents, rest)
    clear = max(CLEAR_RADII * float(np.median(cut.radius[1:])),
                CLEAR_BONE * float(np.median(tree_bone[parents >= 0])) if N > 1 else 0.0)
    t = np.array([0.25, 0.5, 0.75, 1.0])                                 # points along every cut bone ...
    head, tail = cut.rest[cut.parents[1:]], cut.rest[1:]
    along = (head[:, None] + t[None, :, None] * (tail - head)[:, None]).reshape(-1, 3)
    along = along[np.linalg.norm(along, axis=1) > clear]                  # ... off its base
    kd = cKDTree(rest)                                                     # earlier cuts count too
    size = np.append(subtree_sizes(parents), 0.0) / N                          # share of the tree each node carries
    cand = _candidates(parents, radius, frozen, float(cut.radius[0]), None if at is None else np.asarray(at, float), rest)
    psi = 2.0 * np.pi * np.arange(ROLLS) / ROLLS
    best = None
    for A in cand:
        pa = parents[A]
        d = UP if pa < 0 else rest[A] - rest[pa]
        d = d / max(float(np.linalg.norm(d)), 1e-12)
        R = rodrigues(psi[:, None] * d) @ quat_to_matrix(swing(cut.parent_dir, d))     # (ROLLS, 3, 3)
        P = rest[A] + np.einsum("rij,mj->rmi", R, cut.rest)                 # (ROLLS, M, 3)
        ins = inside(P[:, 1:].reshape(-1, 3)).reshape(ROLLS, -1).mean(axis=1)
        hit, damage = np.zeros(ROLLS), np.zeros(ROLLS)
        if len(along):
            Q = rest[A] + np.einsum("rij,mj->rmi", R, along)                # (ROLLS, Q, 3)
            dist, idx = kd.query(Q.reshape(-1, 3), k=NEAR_K, distance_upper_bound=clear)
            hit = np.isfinite(dist[:, 0]).reshape(ROLLS, -1).mean(axis=1)
            spared = np.append(ancestors(parents, A), False)[idx]             # the base's own way down stays
            damage = np.where(spared, 0.0, size[idx]).reshape(ROLLS, -1).max(axis=1)
        score = ins - hit - damage - (0.0 if at is not None else
                                      abs(math.log(max(radius[A], 1e-9) / max(cut.radius[0], 1e-9))))
        k = int(np.argmax(score))
        if best is None or score[k] > best[0] + 1e-12:
            best = (float(score[k]), int(A), P[k], float(psi[k]), float(ins[k]))
    if best is None:
        raise InputError("the tree has no node a cut can hang from; grow it with more nodes")
    _, A, P, roll, inside_share = best

    # 3. take off the tree's branches that come within the clearance of the cut
    keep_safe = ancestors(parents, A) | carriers(parents, frozen)
    child = np.flatnonzero((parents >= 0) & ~keep_safe)
    mid = 0.5 * (rest[child] + rest[parents[child]])
    ca, cb = P[cut.parents[1:]], P[1:]
    near = (segment_distance(mid, ca, cb) < clear) | (segment_distance(rest[child], ca, cb) < clear)
    # a bone of A's own starts on the cut's base: only its tail counts
    at_base = parents[child] == A
    near = np.where(at_base, segment_distance(rest[child], ca, cb) < clear, near)
    off = subtree(parents, child[near]) & ~keep_safe
    stumps = np.unique(parents[child[near]])
    keep, new_par, index = without_nodes(parents, off)
    M = len(cut.parents)
    cut_par = np.where(cut.parents[1:] == 0, index[A], len(keep) + cut.parents[1:] - 1)
    par = np.concatenate([new_par, cut_par]).astype(np.int64)
    pos = np.vstack([rest[keep], P[1:]])
    cut_idx = np.concatenate([-np.ones(len(keep), np.int64), np.arange(1, M)])

    # 4. grow back as many nodes from the stumps, around the cut
    regrown, n_off = 0, int(off.sum())
    if n_off and len(stumps):
        from .colonize import colonize
        step = float(np.median(tree_bone[parents >= 0]))
        lo, hi = pos.min(0) - step, pos.max(0) + step
        pts = lo + (hi - lo) * rng.random((max(8 * n_off, 64), 3))
        ok = inside(pts) & (segment_distance(pts, ca, cb) > 2 * clear)
        pts = pts[ok]

        def room(q: np.ndarray) -> np.ndarray:
            return np.asarray(inside(q), bool) & (segment_distance(q, ca, cb) > clear)
        growing = np.zeros(len(par), bool)                  # the stumps and the tree's own tips (a stump
        growing[index[stumps[index[stumps] >= 0]]] = True   # at the cut's base has no room to grow)
        kids = np.bincount(par[par >= 0], minlength=len(par))
        growing |= (kids == 0) & (cut_idx < 0) & ~np.concatenate([frozen[keep], np.ones(M - 1, bool)])
        if len(pts) and growing.any():
            col = colonize(par, pos, growing, pts, step, 4.0 * step, 0.5 * step, budget=len(par) + n_off, inside=room)
            regrown = len(col.parents) - len(par)
            par, pos = col.parents.astype(np.int64), col.pos
            cut_idx = np.concatenate([cut_idx, -np.ones(regrown, np.int64)])
    cut_radius = np.full(len(par), np.nan)
    cut_radius[cut_idx >= 0] = cut.radius[cut_idx[cut_idx >= 0]]
    info = {"source": cut.source, "bones": int(cut.n_bones), "base_node": int(index[A]),
            "first_node": int(len(keep)), "at": None if at is None else [float(v) for v in at],
            "placed": "at" if at is not None else "fit", "roll_deg": round(math.degrees(roll), 3),
            "inside_share": round(inside_share, 4), "clearance_m": round(clear, 5),
            "taken_off": n_off, "regrown": int(regrown)}
    return Placed(par.astype(np.int32), pos, cut_idx.astype(np.int32), cut_radius, keep, info)


def place_cuts(parents: np.ndarray, rest: np.ndarray, radius_fn: Callable[[np.ndarray, np.ndarray], np.ndarray],
               cuts: Sequence[tuple[TreeCut, np.ndarray | None]], inside=None,
               rng: np.random.Generator | None = None) -> Placed:
    """Every ``(cut, at)`` of ``cuts`` placed in turn (:func:`place_cut`), a cut never on or through
    an earlier one; ``radius_fn(parents, rest) → (N,)`` metres the tree's radii before each
    placement. ``Placed.cut`` numbers cut nodes ``CUT_IDS · k + i`` (cut k, its node i); ``info``
    ``{"cuts": [each cut's info]}``."""
    par, pos = np.asarray(parents, np.int64), np.asarray(rest, np.float64)
    cut_id = -np.ones(len(par), np.int64)
    cut_r = np.full(len(par), np.nan)
    is_base = np.zeros(len(par), bool)
    infos = []
    for k, (cut, at) in enumerate(cuts):
        taken = (cut_id >= 0) | is_base               # earlier cuts' nodes and bases: no base for this one
        placed = place_cut(par, pos, radius_fn(par, pos), cut, at, inside, taken, rng)
        K = len(placed.kept)
        new_id = -np.ones(len(placed.parents), np.int64)
        new_r = np.full(len(placed.parents), np.nan)
        new_id[:K], new_r[:K] = cut_id[placed.kept], cut_r[placed.kept]          # earlier cuts' nodes
        new_base = np.zeros(len(placed.parents), bool)
        new_base[:K] = is_base[placed.kept]
        new_base[placed.info["base_node"]] = True
        is_base = new_base
        mine = placed.cut >= 0
        new_id[mine] = CUT_IDS * k + placed.cut[mine]
        new_r[mine] = placed.cut_radius[mine]
        par, pos, cut_id, cut_r = placed.parents.astype(np.int64), placed.rest, new_id, new_r
        infos.append(placed.info)
    for k, info in enumerate(infos):                  # later placements re-number earlier cuts' nodes
        of_k = np.flatnonzero(cut_id // CUT_IDS == k)
        first = int(of_k[np.argmin(cut_id[of_k])])
        info.update(first_node=first, base_node=int(par[first]))
    return Placed(par.astype(np.int32), pos, cut_id.astype(np.int32), cut_r, np.arange(len(par)), {"cuts": infos})
