"""Levels of detail for game engines (issue 33): LOD0..LOD(K−1) of one tree from the same skeleton
and motion, each a branch mesh and leaf cards with about :func:`lod_shares` of LOD0's triangles
(100 %, 40 %, 15 %, then ×0.4 a level).

How a level meets its share ``s`` of LOD0's triangles ``T₀ = T_b + T_l`` (branches, leaves):

* **Branches** keep their share of the level, ``s·T_b``: the tubes are rebuilt with fewer rings
  ``K`` and sides ``S`` (``2(K − 1)S + 2(S − 2)`` triangles a tube), the thickest with the setting
  just over a tube's share and the rest just under it, in the proportion that meets ``s·T_b``,
  each widened to LOD0's mean width; below 2 rings of 3 sides the tubes lose their end caps, then
  the thinnest tubes are left out (twigs first; never the trunk: the leaves of a dropped twig stay
  where they were).
* **Leaves** take what is left, ``s·T₀ − T_b(level)``: every cluster keeps ``m`` of its ``C``
  cards, spread over its template (a frond keeps whole leaflet pairs along its midrib), each kept
  card scaled by ``√(C/m)`` about its stem (at most ×2.5) so the crown keeps its cover.

Every level's vertices keep their bones (the LODs share one rig). LOD0's forks join into one
surface (:mod:`core.detail.forks`); the lower levels mix two tube settings bone by bone, so their
tubes overlap at the forks as game LODs usually do, with the joined forks' radii. LOD0's cards keep their flap;
lower levels carry none (a morph target a game pays for on every level; engines flutter leaves in
the shader).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import bones
from ..tree3d import Tree3D
from .look import Look
from .meshes import BranchMesh, LeafMesh, branch_arrays
from .roles import TRUNK, TWIG, node_roles

#: each level's share of the level before it after LOD1 (LOD1 = 40 %, LOD2 = 15 % of LOD0)
LATER_SHARE = 0.4
#: the largest scale a kept leaf card gets (a level keeping very few cards thins the crown)
MAX_CARD_SCALE = 2.5
#: the most levels an export may ask for (the last at 0.15 · 0.4⁴ ≈ 0.4 % of LOD0)
MAX_LODS = 6


@dataclass
class Lod:
    """One level: ``branches`` (None: the tree has no branch mesh), ``leaves`` (None: no leaves),
    ``share`` the triangles asked for as a share of LOD0's; ``thick`` and ``thin`` the ``(sides,
    rings)`` of its thickest ``n_thick`` tubes and of the others; ``cards`` leaf cards kept per
    cluster on average; ``dropped`` branch bones whose tube was left out."""

    branches: BranchMesh | None
    leaves: LeafMesh | None
    share: float
    thick: tuple[int, int] = (0, 0)
    thin: tuple[int, int] = (0, 0)
    n_thick: int = 0
    cards: float = 0.0
    dropped: int = 0

    @property
    def triangles(self) -> int:
        return branch_triangles(self.branches) + (0 if self.leaves is None else 2 * self.leaves.quads)


def lod_shares(count: int) -> tuple[float, ...]:
    """The triangle share of LOD0 each of ``count`` levels aims at: 1, 0.4, 0.15, then ×0.4."""
    out = [1.0, 0.4, 0.15][:count]
    while len(out) < count:
        out.append(out[-1] * LATER_SHARE)
    return tuple(out)


def branch_triangles(mesh: BranchMesh | None) -> int:
    """Triangles of a branch mesh (a quad 2, an S-gon cap S − 2)."""
    return 0 if mesh is None else int(np.sum(mesh.loop_total - 2))


def tube_triangles(sides: int, rings: int) -> int:
    """Triangles of one tube: ``2(K − 1)S`` on its side, ``S − 2`` per cap."""
    return 2 * (rings - 1) * sides + 2 * (sides - 2)


def mean_width(sides: int) -> float:
    """A regular ``sides``-gon's mean width over all directions, in units of its circumradius: its
    perimeter over π (Cauchy), ``2S·sin(π/S)/π`` (2 for a circle)."""
    return 2.0 * sides * np.sin(np.pi / sides) / np.pi


def tube_ladder(sides: int, rings: int) -> list[tuple[int, int]]:
    """The tube settings a level may use, richest first: LOD0's ``(sides, rings)``, then one side
    fewer a step with the rings in proportion (at least 2), down to ``(3, 2)``: a sparser tube is
    never richer in either."""
    return [(s, max(2, int(round(rings * s / sides)))) for s in range(sides, 2, -1)] or [(3, 2)]


def tube_settings(sides: int, rings: int, budget: float) -> tuple[tuple[int, int], tuple[int, int]]:
    """The two steps of :func:`tube_ladder` that bracket ``budget`` triangles a tube: the richest
    at or under it and the next richer one (the sparsest step twice when none fits; LOD0's twice
    when it fits)."""
    ladder = tube_ladder(sides, rings)
    under = [k for k, (s, r) in enumerate(ladder) if tube_triangles(s, r) <= budget]
    if not under:
        return ladder[-1], ladder[-1]
    k = under[0]
    return ladder[k], ladder[max(k - 1, 0)]


def kept_cards(cards: int, keep: int, paired: bool) -> np.ndarray:
    """Indices of the ``keep`` of a cluster's ``cards`` cards a level keeps, spread evenly over the
    template (``paired``: whole left/right pairs, a frond's leaflets)."""
    keep = int(np.clip(keep, 1, cards))
    if paired and cards >= 2:
        pairs = cards // 2
        n = max(1, min(pairs, int(round(keep / 2))))
        p = np.unique(np.round(np.linspace(0, pairs - 1, n)).astype(int))
        return np.sort(np.concatenate([2 * p, 2 * p + 1]))
    return np.unique(np.round(np.linspace(0, cards - 1, keep)).astype(int))


def thin_leaves(leaves: LeafMesh, cards: int, per_cluster: float, paired: bool) -> tuple[LeafMesh, float]:
    """``leaves`` keeping ``per_cluster`` cards a cluster on average (cluster ``c``'s cards are
    quads ``c·cards …``): every cluster keeps ``m`` or the next count up (:func:`kept_cards`; a
    seeded share of the clusters the larger, so the average is met; below one card a cluster,
    the others keep none), each kept card scaled by
    ``√(cards / m)`` (≤ :data:`MAX_CARD_SCALE`) about its stem (the midpoint of its first two
    corners); no flap. Returns the mesh and the cards kept per cluster on average."""
    clusters = leaves.quads // cards
    step = 2 if paired and cards >= 2 else 1
    x = float(np.clip(per_cluster, 0.0, cards)) / step
    lo_n = int(np.floor(x))
    hi_n = min(lo_n + 1, cards // step)
    rng = np.random.default_rng(0x10D)
    more = rng.permutation(clusters) < int(round((x - lo_n) * clusters)) if hi_n > lo_n else np.zeros(clusters, bool)
    mask = np.zeros((clusters, cards), bool)
    scale = np.empty(clusters)
    for n, rows in ((lo_n, ~more), (hi_n, more)):
        if n == 0:                      # below one card (a pair) a cluster: a share of clusters keeps none
            scale[rows] = 1.0
            continue
        keep = kept_cards(cards, n * step, paired)
        mask[np.ix_(rows, keep)] = True
        scale[rows] = min(float(np.sqrt(cards / len(keep))), MAX_CARD_SCALE)
    quad = np.flatnonzero(mask.ravel())
    rows4 = (quad[:, None] * 4 + np.arange(4)[None]).ravel()
    co = leaves.co[rows4].reshape(-1, 4, 3).astype(np.float64)
    stem = 0.5 * (co[:, 0] + co[:, 1])
    f = scale[quad // cards][:, None, None]
    co = stem[:, None] + f * (co - stem[:, None])
    mesh = LeafMesh(co.reshape(-1, 3).astype(np.float32), leaves.uv[rows4], leaves.colour[rows4], leaves.bone[rows4], None)
    return mesh, len(quad) / max(clusters, 1)


def tube_subset(mesh: BranchMesh, keep: np.ndarray) -> BranchMesh:
    """``mesh`` with only the tubes of bones ``keep (B,)`` bool (polygons contiguous per bone,
    :func:`core.detail.branch_mesh.tube_arrays`)."""
    poly_bone = mesh.bone[mesh.loop_vert[mesh.loop_start]]
    keep_poly = keep[poly_bone]
    keep_vert = keep[mesh.bone]
    new_index = np.cumsum(keep_vert) - 1
    loop_keep = np.repeat(keep_poly, mesh.loop_total)
    totals = mesh.loop_total[keep_poly]
    starts = np.concatenate([[0], np.cumsum(totals)[:-1]]).astype(np.int32)
    return BranchMesh(mesh.co[keep_vert], new_index[mesh.loop_vert[loop_keep]].astype(np.int32), starts,
                      totals.astype(np.int32), mesh.smooth[keep_poly], mesh.uv[loop_keep], mesh.bone[keep_vert])


def without_caps(mesh: BranchMesh) -> BranchMesh:
    """``mesh`` without its tubes' end caps (its flat-shaded polygons, :func:`core.detail.
    branch_mesh.tube_arrays`); the vertices stay (the sides use them all)."""
    side = mesh.smooth
    loop_keep = np.repeat(side, mesh.loop_total)
    totals = mesh.loop_total[side]
    starts = np.concatenate([[0], np.cumsum(totals)[:-1]]).astype(np.int32)
    return BranchMesh(mesh.co, mesh.loop_vert[loop_keep], starts, totals.astype(np.int32), side[side],
                      mesh.uv[loop_keep], mesh.bone)


def join_tubes(a: BranchMesh, b: BranchMesh) -> BranchMesh:
    """Two branch meshes as one (``b``'s vertices after ``a``'s)."""
    return BranchMesh(np.concatenate([a.co, b.co]), np.concatenate([a.loop_vert, b.loop_vert + len(a.co)]),
                      np.concatenate([a.loop_start, b.loop_start + len(a.loop_vert)]).astype(np.int32),
                      np.concatenate([a.loop_total, b.loop_total]), np.concatenate([a.smooth, b.smooth]),
                      np.concatenate([a.uv, b.uv]), np.concatenate([a.bone, b.bone]))


def level_tubes(tree: Tree3D, rest: np.ndarray, look: Look, role: np.ndarray, thick: np.ndarray,
                allowed: float) -> tuple[BranchMesh, tuple[int, int], tuple[int, int], int, int]:
    """The tubes of a level with at most about ``allowed`` triangles: the thickest tubes with the
    sparser setting over a tube's share and the others with the richer one under it
    (:func:`tube_settings`) in the proportion that meets ``allowed``; when even every tube at
    the sparsest setting is over, the thinnest tubes left out (twigs first, never the trunk).
    Returns the mesh, the thick and thin settings ``(sides, rings)``, how many tubes are thick,
    how many were left out."""
    # a level mixes two tube settings bone by bone; its tubes too few to carry the bark's relief
    p0 = replace(look.mesh, forks="overlap", relief_cm=0.0)
    B = len(rest)
    (ls, lk), (hs, hk) = tube_settings(p0.sides, p0.ring_count(), allowed / max(B, 1))
    lo_t, hi_t = tube_triangles(ls, lk), tube_triangles(hs, hk)
    # a tube of fewer sides is widened to LOD0's mean width: its silhouette keeps its thickness
    S0 = p0.sides
    thin_mesh = branch_arrays(tree, rest, replace(p0, sides=ls, rings=lk), mean_width(S0) / mean_width(ls))
    n_hi = 0
    if hi_t > lo_t:
        n_hi = int(np.clip(np.floor((allowed - B * lo_t) / (hi_t - lo_t)), 0, B))
    if n_hi:
        thick_bones = np.zeros(B, bool)
        thick_bones[np.argsort(-thick, kind="stable")[:n_hi]] = True
        rich = branch_arrays(tree, rest, replace(p0, sides=hs, rings=hk), mean_width(S0) / mean_width(hs))
        mesh = join_tubes(tube_subset(rich, thick_bones), tube_subset(thin_mesh, ~thick_bones))
        return mesh, (hs, hk), (ls, lk), n_hi, 0
    dropped = 0
    mesh = thin_mesh
    if branch_triangles(mesh) > allowed:          # the caps go first (a tube's ends, hidden in its parent
        mesh = without_caps(mesh)                  # or a dot at a tip): 2(S − 2) of a tube's triangles
        lo_t = tube_triangles(ls, lk) - 2 * (ls - 2)
    if branch_triangles(mesh) > allowed:
        mesh, dropped = drop_thin(mesh, role, thick, lo_t, allowed)
    return mesh, (ls, lk), (ls, lk), 0, dropped


def tree_lods(tree: Tree3D, rest: np.ndarray, look: Look, branches: BranchMesh | None,
              leaves: LeafMesh | None, count: int) -> list[Lod]:
    """``count`` levels of ``tree`` (module docstring); ``rest (B, 3, 3)`` the branch bones' rest
    rotations, ``branches`` and ``leaves`` LOD0's meshes (the full rig's bone indices), ``look`` the
    tubes' settings. Level 0 is LOD0's meshes themselves."""
    if not 1 <= int(count) <= MAX_LODS:
        raise ValueError(f"LOD count {count} must be 1 to {MAX_LODS}")
    shares = lod_shares(int(count))
    p0 = look.mesh
    S0, K0 = p0.sides, p0.ring_count()
    cards = tree.leaves.cards if leaves is not None and tree.leaves is not None else 0
    paired = leaves is not None and tree.leaves is not None and tree.leaves.shape == "frond"
    Tb, Tl = branch_triangles(branches), 0 if leaves is None else 2 * leaves.quads
    full = (S0, K0) if branches is not None else (0, 0)
    out = [Lod(branches, leaves, 1.0, full, full, len(rest) if branches is not None else 0, float(cards))]
    # the tubes' roles and thickness decide which go first when even the sparsest tubes are too many
    child = bones.bone_edges(tree.parents)[:, 1]        # bone b ends at node child[b]
    role = node_roles(tree)[child]
    thick = np.asarray(tree.radius, np.float64)[child]
    for share in shares[1:]:
        b_mesh, thick_set, thin_set, n_thick, dropped = None, (0, 0), (0, 0), 0, 0
        if branches is not None:
            b_mesh, thick_set, thin_set, n_thick, dropped = level_tubes(tree, rest, look, role, thick, share * Tb)
        l_mesh, kept = None, 0.0
        if leaves is not None and cards:
            room = share * (Tb + Tl) - branch_triangles(b_mesh)
            l_mesh, kept = thin_leaves(leaves, cards, room / max(Tl, 1) * cards, paired)
        out.append(Lod(b_mesh, l_mesh, share, thick_set, thin_set, n_thick, kept, dropped))
    return out


def drop_thin(mesh: BranchMesh, role: np.ndarray, thick: np.ndarray, per_tube: int,
              allowed: float) -> tuple[BranchMesh, int]:
    """``mesh`` without the thinnest tubes (twigs before limbs; never the trunk's) until its
    triangles fit ``allowed``; returns it and how many tubes went. Each tube is ``per_tube``
    triangles, its polygons contiguous per bone in bone order (:func:`core.detail.branch_mesh.
    tube_arrays`)."""
    B = len(role)
    over = branch_triangles(mesh) - allowed
    n_drop = int(np.ceil(over / max(per_tube, 1)))
    candidates = np.flatnonzero(role != TRUNK)
    # twigs first, then by radius, thinnest first
    order = candidates[np.lexsort((thick[candidates], role[candidates] != TWIG))]
    drop = np.zeros(B, bool)
    drop[order[:n_drop]] = True
    return tube_subset(mesh, ~drop), int(drop.sum())
