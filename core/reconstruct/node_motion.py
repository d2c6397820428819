"""How the 2D skeleton's nodes move: each node follows the tracks near it.

A node's displacement since frame 1 in frame t is the weighted mean, over the tracks valid in t,
of each track's move since its birth plus the node's own displacement when that track was born:

    d_n(t) = Σ_k w_nk (p_k(t) − p_k(b_k) + d_n(b_k)) / Σ_k w_nk          (eq. d_n(t))

weights ``w = exp(−d² / 2s²)`` on the distance d between node and track *where the track was born*
(b_k = frame 1 for the first corners, the frame of its detection for the re-detected ones,
measured against the node's position in that frame: a late track is never matched through an
estimated frame-1 position; a column that holds a new track forgets its last one's pairs).
Anchoring each track at its birth, rather than chaining the mean of per-frame steps, keeps a
node from drifting as the set of tracks around it changes: the frame-to-frame chain summed every
step's error (on a clip of fluttering leaves, tips' low-frequency error 5.1 → 3.4 px rms).
The scale s is the tree's (``scale``, 2 % of its size) or, for a node whose crown has sparser
corners, the distance to its 5th nearest track of frame 1 (at most 4 × that): at 160 × 120 px
the corners' 3 px spacing exceeded the tree's 2 % (1.8 px), so nodes had about one track within
their scale, and a clip the nodes followed at 0.99 correlation said its motion was unmeasured
at 97 % of node-frames (after: 0 %). Where no track within 3s is valid, a wider neighbourhood
(4s) is used, and where none of those either, the node's last position plus the crown's median
step: a node never freezes because its own tracks died. When the tracks carry the dense flow from
frame 1 (:mod:`.dense_flow`), each node and frame is fused with it (eq. fuse, :func:`fuse`)
as soon as it is estimated, so a track born later is anchored at the fused displacement d_n(b_k):
anchored on the tracks alone, a node dragged by a branch swinging in front of it kept that error
after the branch had gone (2D tip correlation, fused at the end → as it goes: variable frame rate
0.77 → 0.80, 1080p 0.90 → 0.93, foreground branch 0.54 → 0.57; 3D, variable frame rate 0.77 → 0.85).

The motion confidence of a node in a frame is ``1 − exp(−n / 2)`` with n the summed weight of the
tracks it followed (n ≈ how many tracks within s; the wider fallback counts 1/16 of a track per
track, the crown's median step nothing), in [0, 1): 0.5 at 1.4 tracks, 0.78 at 3, 0.92 at 5.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .tracks import Tracks

#: confidence below which a node-frame counts as poorly measured (≈ 1.4 tracks within the scale)
LOW_CONFIDENCE = 0.5
WIDE = 4.0            # the fallback neighbourhood, × scale
#: flow px (its images: the tree at most TrackParams.flow_max_px): the dense flow's forward–backward
#: disagreement at which its confidence is e^(−1/2) = 0.61; half the tracks' own limit
#: (TrackParams.fb_max_error = 1 px marks a track lost)
FLOW_FB_PX = 0.5
#: a node's scale grows to reach this many of frame 1's tracks (up to WIDE × scale): then the
#: k·e^(−1/2) ≈ 3 weight of its nearest tracks keeps its confidence at 0.5 after half are lost
K_NEAREST = 5
REACH = 3.0           # pairs farther than this × the neighbourhood's scale are left out


@dataclass
class NodeMotion:
    """``nodes (F, N, 2)`` float32 px per frame (frame-1 coordinates); ``confidence (F, N)`` float32
    in [0, 1] (frame 1 and fixed nodes such as the trunk base: 1), see the module docstring."""

    nodes: np.ndarray
    confidence: np.ndarray


def low_share(confidence: np.ndarray) -> float:
    """Share of node-frames after frame 1 with confidence below :data:`LOW_CONFIDENCE`."""
    c = np.asarray(confidence)[1:]
    return float((c < LOW_CONFIDENCE).mean()) if c.size else 0.0


def confidence_summary(confidence: np.ndarray) -> str:
    """One line for the operators' reports and the batch output: the share of node-frames measured."""
    return f"motion measured at {1 - low_share(confidence):.0%} of node-frames (confidence >= {LOW_CONFIDENCE})"


def confidence_warning(confidence: np.ndarray, limit: float = 0.1) -> str | None:
    """A warning naming the share of poorly measured node-frames when it exceeds ``limit``."""
    share = low_share(confidence)
    if share <= limit:
        return None
    return (f"the motion is poorly measured at {share:.0%} of node-frames (motion confidence below "
            f"{LOW_CONFIDENCE}: under ~1.4 live tracks near the node); there the nodes follow their "
            "neighbourhood or the crown — a sharper or steadier clip, or a tighter outline, helps")


def node_scales(nodes: np.ndarray, pts: np.ndarray, scale: float, k: int = K_NEAREST) -> np.ndarray:
    """``(N,)`` px: each node's Gaussian scale, ``scale`` or, where the crown's corners are sparser,
    the distance to its ``k``-th nearest track ``pts (P, 2)`` (at most ``WIDE · scale``)."""
    s = np.full(len(nodes), float(scale))
    if len(pts) == 0 or len(nodes) == 0 or k <= 0:
        return s
    d, _ = cKDTree(pts).query(nodes, k=min(k, len(pts)))
    dk = d if d.ndim == 1 else d[:, -1]
    return np.clip(dk, scale, WIDE * scale)


def _pairs(nodes: np.ndarray, pts: np.ndarray, cols: np.ndarray, s: np.ndarray | float, n_tracks: int) -> sp.csr_matrix:
    """``(N, P)`` sparse Gaussian weights between ``nodes (N, 2)`` and the tracks ``cols`` at
    ``pts (len(cols), 2)``, for pairs within ``REACH · s``; ``s`` px, one or per node."""
    if len(pts) == 0:
        return sp.csr_matrix((len(nodes), n_tracks))
    s = np.broadcast_to(np.asarray(s, np.float64), (len(nodes),))
    hits = cKDTree(pts).query_ball_point(nodes, REACH * s)       # per node: track rows within reach
    rows = np.repeat(np.arange(len(nodes)), [len(h) for h in hits])
    c = np.fromiter(itertools.chain.from_iterable(hits), int, count=len(rows))
    dist = np.linalg.norm(nodes[rows] - pts[c], axis=1)
    w = np.exp(-dist ** 2 / (2 * s[rows] ** 2))
    return sp.csr_matrix((w, (rows, cols[c])), shape=(len(nodes), n_tracks))


def follow_tracks(nodes0: np.ndarray, tracks: Tracks, scale: float,
                  fixed: np.ndarray | None = None, k_nearest: int = K_NEAREST) -> NodeMotion:
    """Move nodes ``(N, 2)`` (frame-1 px) with the tracks near them, fused with ``tracks.flow``
    where there is one (see the module docstring); ``scale`` px; ``fixed (N,)`` bool marks nodes
    that never move (the trunk base); ``k_nearest`` the frame-1 tracks each node's scale grows to
    reach (0: ``scale`` for every node)."""
    F, P = tracks.points.shape[:2]
    N = len(nodes0)
    out = np.repeat(np.asarray(nodes0, np.float64)[None], F, axis=0)
    conf = np.ones((F, N), np.float32)
    if P == 0 or F < 2 or N == 0:
        return NodeMotion(out.astype(np.float32), conf)
    valid = tracks.valid
    points = tracks.points.astype(np.float64)
    born = tracks.births()                   # (F, P): a column may hold several late tracks, one
                                             # after another (Tracks' docstring)
    starts = np.flatnonzero(born[:-1].any(1))
    ends = np.append(starts[1:], F - 1)
    # per neighbourhood (scale, WIDE · scale): pair weights w (N, P) and the weights times the
    # node's displacement at the track's birth, x and y (the anchors of eq. d_n(t) below)
    near, wide = _Pairs(N, P), _Pairs(N, P)
    s_n = node_scales(out[0], points[0, valid[0]], scale, k_nearest)
    by_flow = flow_positions(out[0], tracks, fixed)
    origin = np.zeros((P, 2))                # each column's track's position at its birth
    for a, b in zip(starts, ends):
        cols = np.flatnonzero(born[a])
        origin[cols] = points[a, cols]
        # pairs go with their track: a column's old track when a new one is born in it, and every
        # track lost before this segment (lost stays lost: it would only add zeros to each product)
        keep = (valid[a] & ~born[a]).astype(np.float64)
        near.drop(keep)
        wide.drop(keep)
        X = out[a]
        d_a = X - out[0]                     # the nodes' displacement when these tracks are born
        near.add(_pairs(X, origin[cols], cols, s_n, P), d_a)
        wide.add(_pairs(X, origin[cols], cols, WIDE * s_n, P), d_a)
        T = b - a
        # tracks live in the segment's frames; those born in its last frame b count from b + 1
        va = (valid[a + 1:b + 1] & ~born[a + 1:b + 1]).T.astype(np.float64)        # (P, T)
        moved = (points[a + 1:b + 1] - origin[None]).transpose(1, 0, 2) * va[..., None]
        moved = moved.reshape(P, 2 * T)                                           # (P, T·2)
        num1, den1 = near.estimate(moved, va)
        num2, den2 = wide.estimate(moved, va)
        ok1 = den1 > 1e-6
        ok2 = ~ok1 & (den2 > 1e-6)
        disp = np.zeros((N, T, 2))
        disp[ok1] = num1[ok1] / den1[ok1][:, None]
        disp[ok2] = num2[ok2] / den2[ok2][:, None]
        rest = ~ok1 & ~ok2
        if rest.any():                       # no track near: the last position + the crown's median step
            prev = d_a
            for k in range(T):
                r = rest[:, k]
                if r.any():
                    live = valid[a + k] & valid[a + k + 1]
                    crown = np.median(points[a + k + 1, live] - points[a + k, live], axis=0) if live.any() else 0.0
                    disp[r, k] = prev[r] + crown
                prev = disp[:, k]
        n_eff = np.where(ok1, den1, np.where(ok2, den2 / 16.0, 0.0))
        conf[a + 1:b + 1] = (1.0 - np.exp(-n_eff / 2.0)).T
        if fixed is not None:
            disp[fixed] = 0.0
            conf[a + 1:b + 1, fixed] = 1.0
        out[a + 1:b + 1] = out[0][None] + disp.transpose(1, 0, 2)
        if by_flow is not None:              # fused now: the next segment's births anchor on it
            x_f, c_f = by_flow
            out[a + 1:b + 1], conf[a + 1:b + 1] = fuse(out[a + 1:b + 1], conf[a + 1:b + 1],
                                                      x_f[a + 1:b + 1], c_f[a + 1:b + 1])
    return NodeMotion(out.astype(np.float32), conf)


def flow_positions(nodes0: np.ndarray, tracks: Tracks, fixed: np.ndarray | None = None,
                   fb_px: float = FLOW_FB_PX) -> tuple[np.ndarray, np.ndarray] | None:
    """Where the dense flow from frame 1 (``tracks.flow``) puts the nodes ``nodes0 (N, 2)`` frame-1
    px in every frame: ``x_f (F, N, 2)`` frame-1 px (camera motion removed) and its confidence
    ``c_f (F, N)`` = exp(−e² / 2 fb_px²) from the flow's forward–backward disagreement e (the
    flow's px); 0 in frame 1 and at ``fixed`` nodes. None without a flow."""
    flow = tracks.flow
    F, N = tracks.points.shape[0], len(nodes0)
    if flow is None or len(flow.frames) == 0 or F < 2 or N == 0:
        return None
    d, e = flow.sample(np.asarray(nodes0, np.float64), F)
    img = np.asarray(nodes0, np.float64)[None] + d                    # where the flow puts them (image px)
    cam = tracks.camera[:F].astype(np.float64)
    x_f = np.einsum("fij,fnj->fni", cam[:, :, :2], img) + cam[:, None, :, 2]   # frame-1 coordinates
    c_f = np.exp(-np.square(e, dtype=np.float64) / (2.0 * fb_px * fb_px))
    c_f[0] = 0.0
    if fixed is not None:
        c_f[:, fixed] = 0.0
    return x_f, c_f


def fuse(x: np.ndarray, c: np.ndarray, x_f: np.ndarray, c_f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eq. fuse: positions ``x (..., 2)`` with confidence ``c (...)`` and the flow's ``x_f``, ``c_f``:

        x = (c · x + c_f · x_f) / (c + c_f),   confidence 1 − (1 − c)(1 − c_f)     (eq. fuse)
    """
    c = np.asarray(c, np.float64)
    w = (c / np.maximum(c + c_f, 1e-12))[..., None]
    return w * x + (1.0 - w) * x_f, 1.0 - (1.0 - c) * (1.0 - c_f)


class _Pairs:
    """The node-track pairs of one neighbourhood: weights ``w (N, P)`` and ``w · d_n(b_k)`` per axis,
    d_n(b_k) the node's displacement in the frame its pair's track was born (sparse, one pattern)."""

    def __init__(self, n: int, p: int) -> None:
        self.w = sp.csr_matrix((n, p))
        self.anchor = [sp.csr_matrix((n, p)), sp.csr_matrix((n, p))]

    def drop(self, keep: np.ndarray) -> None:
        """Forget the pairs of the columns where ``keep (P,)`` is 0."""
        k = keep[None, :]
        self.w = self._pruned(self.w.multiply(k))
        self.anchor = [self._pruned(m.multiply(k)) for m in self.anchor]

    @staticmethod
    def _pruned(m) -> sp.csr_matrix:
        out = sp.csr_matrix(m)
        out.eliminate_zeros()
        return out

    def add(self, w: sp.csr_matrix, disp: np.ndarray) -> None:
        """New pairs ``w (N, P)`` whose tracks are born now, the nodes displaced by ``disp (N, 2)``."""
        self.w = self.w + w
        self.anchor = [m + sp.csr_matrix(w.multiply(disp[:, i:i + 1])) for i, m in enumerate(self.anchor)]

    def estimate(self, moved: np.ndarray, live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Numerator ``(N, T, 2)`` and denominator ``(N, T)`` of eq. d_n(t) for the tracks' moves
        since their birth ``moved (P, T·2)`` (0 where dead) and ``live (P, T)`` 0/1."""
        den = self.w @ live
        N, T = den.shape
        num = (self.w @ moved).reshape(N, T, 2) + np.stack([m @ live for m in self.anchor], -1)
        return num, den
