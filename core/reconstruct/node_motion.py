"""How the 2D skeleton's nodes move: each node follows the tracks near it.

Per frame, a node's step is the weighted mean of the steps of the tracks valid in both frames,
weights ``w = exp(−d² / 2s²)`` on the distance d between node and track *where the track was born*
(frame 1 for the first corners, the frame of its detection for the re-detected ones, measured
against the node's position in that frame: a late track is never matched through an estimated
frame-1 position; a column that holds a new track forgets its last one's weights). Where no
track within 3s is valid, a wider neighbourhood (4s) is used, and where none of those either, the
crown's median step: a node never freezes because its own tracks died.
The steps are summed over frames (chained).

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


def _pairs(nodes: np.ndarray, pts: np.ndarray, cols: np.ndarray, s: float, n_tracks: int) -> sp.csr_matrix:
    """``(N, P)`` sparse Gaussian weights between ``nodes (N, 2)`` and the tracks ``cols`` at
    ``pts (len(cols), 2)``, for pairs within ``REACH · s``."""
    if len(pts) == 0:
        return sp.csr_matrix((len(nodes), n_tracks))
    hits = cKDTree(pts).query_ball_point(nodes, REACH * s)       # per node: track rows within reach
    rows = np.repeat(np.arange(len(nodes)), [len(h) for h in hits])
    c = np.fromiter(itertools.chain.from_iterable(hits), int, count=len(rows))
    dist = np.linalg.norm(nodes[rows] - pts[c], axis=1)
    w = np.exp(-dist ** 2 / (2 * s * s))
    return sp.csr_matrix((w, (rows, cols[c])), shape=(len(nodes), n_tracks))


def follow_tracks(nodes0: np.ndarray, tracks: Tracks, scale: float,
                  fixed: np.ndarray | None = None) -> NodeMotion:
    """Move nodes ``(N, 2)`` (frame-1 px) with the tracks near them (see the module docstring);
    ``fixed (N,)`` bool marks nodes that never move (the trunk base)."""
    F, P = tracks.points.shape[:2]
    N = len(nodes0)
    out = np.repeat(np.asarray(nodes0, np.float64)[None], F, axis=0)
    conf = np.ones((F, N), np.float32)
    if P == 0 or F < 2 or N == 0:
        return NodeMotion(out.astype(np.float32), conf)
    valid = tracks.valid
    born = tracks.births()                   # (F, P): a column may hold several late tracks, one
                                             # after another (Tracks' docstring)
    steps = (tracks.points[1:] - tracks.points[:-1]).astype(np.float64)      # (F-1, P, 2)
    both = (valid[1:] & valid[:-1])                                          # (F-1, P)
    steps[~both] = 0.0
    bw = both.astype(np.float64)
    starts = np.flatnonzero(born[:-1].any(1))
    ends = np.append(starts[1:], F - 1)
    W1 = sp.csr_matrix((N, P))
    W2 = sp.csr_matrix((N, P))
    X = out[0].copy()
    seen = np.zeros(P, bool)
    for a, b in zip(starts, ends):
        cols = np.flatnonzero(born[a])
        pts = tracks.points[a, cols].astype(np.float64)
        again = cols[seen[cols]]
        if len(again):                       # a column's new track: its last one's pairs go
            keep = np.ones(P)
            keep[again] = 0.0
            W1, W2 = (sp.csr_matrix(W.multiply(keep[None, :])) for W in (W1, W2))
        seen[cols] = True
        W1 = W1 + _pairs(X, pts, cols, scale, P)
        W2 = W2 + _pairs(X, pts, cols, WIDE * scale, P)
        T = b - a
        st = steps[a:b].transpose(1, 0, 2).reshape(P, 2 * T)        # (P, T·2)
        va = bw[a:b].T                                               # (P, T)
        num1 = (W1 @ st).reshape(N, T, 2)
        den1 = W1 @ va
        num2 = (W2 @ st).reshape(N, T, 2)
        den2 = W2 @ va
        ok1 = den1 > 1e-6
        ok2 = ~ok1 & (den2 > 1e-6)
        move = np.zeros((N, T, 2))
        move[ok1] = num1[ok1] / den1[ok1][:, None]
        move[ok2] = num2[ok2] / den2[ok2][:, None]
        rest = ~ok1 & ~ok2
        if rest.any():                                            # the crown's median step
            crown = np.zeros((T, 2))
            for k in np.flatnonzero(rest.any(0)):
                live = both[a + k]
                if live.any():
                    crown[k] = np.median(steps[a + k, live], axis=0)
            move[rest] = np.broadcast_to(crown[None], move.shape)[rest]
        n_eff = np.where(ok1, den1, np.where(ok2, den2 / 16.0, 0.0))
        conf[a + 1:b + 1] = (1.0 - np.exp(-n_eff / 2.0)).T
        if fixed is not None:
            move[fixed] = 0.0
            conf[a + 1:b + 1, fixed] = 1.0
        out[a + 1:b + 1] = X[None] + np.cumsum(move, axis=1).transpose(1, 0, 2)
        X = out[b].copy()
    return NodeMotion(out.astype(np.float32), conf)
