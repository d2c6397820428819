"""Stage 4 — the paper's binary hierarchy: recursive 2-way normalized cut (Shi & Malik 2000).

Affinity between tracks i, j on a sparse kNN graph (frame-1 positions):

    W_ij = exp(-|p_i - p_j|² / 2σ_s²) · exp(-m_ij² / 2σ_m²)

with m_ij the RMS difference of their displacements from frame 1 over the frames where both are
valid (whole-clip displacement, not per-frame steps: real sway can be 0.05–0.1 px per frame).
Each cluster is split by the second-smallest generalized eigenvector of (D − W) y = λ D y,
thresholded where the normalized cut Ncut(A, B) = cut(A,B)/assoc(A,V) + cut(A,B)/assoc(B,V)
is smallest.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import eigsh
from scipy.spatial import cKDTree

from ..progress import ProgressFn, report
from .tracks import Tracks


@dataclass
class HierarchyParams:
    """``levels`` counts the root (6 → up to 32 leaf clusters); ``knn`` graph neighbours."""

    levels: int = 6
    knn: int = 12
    min_cluster: int = 4          # clusters smaller than 2× this are not split
    min_fraction: float = 0.2     # each side keeps at least this share: the paper splits into "halves"
    motion_floor_px: float = 0.3  # σ_m never below this: tracker noise is ~0.1 px
    max_motion_frames: int = 120  # frames sampled evenly for the motion term


@dataclass
class Hierarchy:
    """Binary cluster tree over tracks.

    ``parent (C,)`` int32 (-1 root), ``level (C,)`` int32 (root 0), ``members`` list of C index
    arrays into the tracks (a child's members are a subset of its parent's).
    """

    parent: np.ndarray
    level: np.ndarray
    members: list

    @property
    def leaves(self) -> np.ndarray:
        has_child = np.zeros(len(self.parent), bool)
        has_child[self.parent[self.parent >= 0]] = True
        return np.flatnonzero(~has_child)


def motion_distance(disp: np.ndarray, valid: np.ndarray, i: np.ndarray, j: np.ndarray,
                    chunk: int = 20000) -> tuple[np.ndarray, np.ndarray]:
    """RMS displacement difference (px) of track pairs ``(i, j)`` over commonly valid frames.

    ``disp (F, P, 2)`` displacement from frame 1, ``valid (F, P)``. Returns ``(m, n_common)``.
    """
    m = np.zeros(len(i), np.float32)
    n = np.zeros(len(i), np.int32)
    for s in range(0, len(i), chunk):
        a, b = i[s:s + chunk], j[s:s + chunk]
        both = valid[:, a] & valid[:, b]
        diff = np.where(both[..., None], disp[:, a] - disp[:, b], 0.0)
        cnt = both.sum(0)
        m[s:s + chunk] = np.sqrt((diff ** 2).sum(axis=(0, 2)) / np.maximum(cnt, 1))
        n[s:s + chunk] = cnt
    return m, n


def affinity(tracks: Tracks, params: HierarchyParams, sel_tracks: np.ndarray | None = None) -> sp.csr_matrix:
    """Symmetric sparse ``(P, P)`` affinity of spatial distance × motion similarity (of the tracks
    ``sel_tracks``, default all: then P is theirs)."""
    cols = np.arange(tracks.points.shape[1]) if sel_tracks is None else sel_tracks
    p0 = tracks.points[0, cols].astype(np.float64)
    n = len(p0)
    k = min(params.knn, n - 1)
    dist, idx = cKDTree(p0).query(p0, k=k + 1)
    i = np.repeat(np.arange(n), k)
    j = idx[:, 1:].ravel()
    d = dist[:, 1:].ravel()
    sel = np.unique(np.linspace(0, tracks.n_frames - 1, min(params.max_motion_frames, tracks.n_frames)).astype(int))
    disp = (tracks.points[sel][:, cols] - tracks.points[:1, cols]).astype(np.float32)
    m, common = motion_distance(disp, tracks.valid[sel][:, cols], i, j)
    sigma_s = max(float(np.median(d)), 1e-3)
    enough = common >= max(3, len(sel) // 10)
    sigma_m = max(float(np.median(m[enough])) if enough.any() else 0.0, params.motion_floor_px)
    motion_term = np.where(enough, np.exp(-m.astype(np.float64) ** 2 / (2 * sigma_m ** 2)), np.exp(-0.5))
    w = np.exp(-d ** 2 / (2 * (2 * sigma_s) ** 2)) * motion_term
    W = sp.coo_matrix((w, (i, j)), shape=(n, n)).tocsr()
    return W.maximum(W.T).tocsr()


def fiedler_vector(W: sp.csr_matrix) -> np.ndarray:
    """Second-smallest generalized eigenvector y of (D − W) y = λ D y (connected ``W``).

    Solved as the second-largest eigenvector z of D^-1/2 W D^-1/2, y = D^-1/2 z.
    """
    deg = np.asarray(W.sum(1)).ravel()
    dinv = 1.0 / np.sqrt(np.maximum(deg, 1e-12))
    M = sp.diags(dinv) @ W @ sp.diags(dinv)
    n = W.shape[0]
    if n <= 400:
        vals, vecs = np.linalg.eigh(M.toarray())
        z = vecs[:, -2]
    else:
        rng = np.random.default_rng(0)
        vals, vecs = eigsh(M, k=2, which="LA", tol=1e-6, v0=rng.standard_normal(n), maxiter=5000)
        z = vecs[:, np.argsort(vals)[0]]
    return z * dinv


def best_ncut_split(W: sp.csr_matrix, y: np.ndarray, min_side: int) -> tuple[np.ndarray, float]:
    """Threshold ``y`` where Ncut is smallest; returns (mask of side A, Ncut value).

    Exact over every threshold between consecutive sorted values: an edge (i, j) is cut by the
    split after position s iff min(r_i, r_j) < s <= max(r_i, r_j), with r the sorted rank.
    """
    n = len(y)
    order = np.argsort(y, kind="stable")
    rank = np.empty(n, int)
    rank[order] = np.arange(n)
    C = sp.triu(W, k=1).tocoo()
    lo = np.minimum(rank[C.row], rank[C.col])
    hi = np.maximum(rank[C.row], rank[C.col])
    diffarr = np.zeros(n + 1)
    np.add.at(diffarr, lo + 1, C.data)
    np.add.at(diffarr, hi + 1, -C.data)
    cut = np.cumsum(diffarr)[1:n]            # cut[s-1] = weight cut when the first s go to A
    deg = np.asarray(W.sum(1)).ravel()[order]
    assoc_a = np.cumsum(deg)[:-1]
    total = deg.sum()
    ncut = cut / np.maximum(assoc_a, 1e-12) + cut / np.maximum(total - assoc_a, 1e-12)
    s_all = np.arange(1, n)
    ok = (s_all >= min_side) & (s_all <= n - min_side)
    if not ok.any():
        ok[:] = True
    s = s_all[ok][np.argmin(ncut[ok])]
    side = np.zeros(n, bool)
    side[order[:s]] = True
    return side, float(ncut[s - 1])


def split_cluster(W: sp.csr_matrix, min_side: int) -> np.ndarray:
    """Two-way normalized cut of a (sub)graph; disconnected graphs split along components."""
    ncomp, labels = connected_components(W, directed=False)
    if ncomp > 1:
        sizes = np.bincount(labels)
        order = np.argsort(-sizes)
        # give whole components to the smaller side until balanced
        side = np.zeros(len(labels), bool)
        acc = 0
        for c in order:
            if acc + sizes[c] <= len(labels) / 2 or acc == 0:
                side |= labels == c
                acc += sizes[c]
        if 0 < side.sum() < len(side):
            return side
    y = fiedler_vector(W)
    side, _ = best_ncut_split(W, y, min_side)
    return side


def build_hierarchy(tracks: Tracks, params: HierarchyParams | None = None,
                    progress: ProgressFn | None = None) -> Hierarchy:
    """Recursive binary normalized cut of the tracks detected in frame 1 (:meth:`Tracks.initial`;
    later tracks only add motion) into ``params.levels`` levels; members index all tracks."""
    params = params or HierarchyParams()
    first = tracks.initial()
    n = len(first)
    W = affinity(tracks, params, first) if n > 1 else sp.csr_matrix((n, n))
    parent, level, members = [-1], [0], [np.arange(n)]
    queue = [0]
    expected = 2 ** (params.levels - 1) - 1
    done = 0
    while queue:
        c = queue.pop(0)
        idx = members[c]
        if level[c] >= params.levels - 1 or len(idx) < 2 * params.min_cluster:
            continue
        sub = W[idx][:, idx].tocsr()
        side = split_cluster(sub, max(params.min_cluster, int(params.min_fraction * len(idx))))
        for part in (idx[side], idx[~side]):
            parent.append(c)
            level.append(level[c] + 1)
            members.append(part)
            queue.append(len(members) - 1)
        done += 1
        report(progress, "hierarchy", done / max(expected, 1))
    return Hierarchy(np.array(parent, np.int32), np.array(level, np.int32), [first[m] for m in members])
