"""Stage 5 — the moving 2D skeleton.

Two ways to place the nodes in frame 1 share the same node motion:

* ``paper`` (Appendix A): nodes at the hierarchy's cluster centroids, a trunk base added at the
  bottom of the outline, children folded toward parents root to tip:
  ``x'_i ← x'_i + α (x'_j − x'_i)`` (α = 0.4), stopping at the second-last level.
* ``traced`` (default, :mod:`.trace`): the branches traced in the image, with the hierarchy's
  clusters attached through the crown.

Node motion (:mod:`.node_motion`): every node follows the valid tracks near it, distance-weighted
and chained frame to frame, so a node keeps moving when its own tracks are lost.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..outline import Outline
from ..progress import ProgressFn, report
from ..topology import branching_level, children_lists, edges_of, topological_order
from .hierarchy import Hierarchy
from .node_motion import follow_tracks
from .tracks import Tracks

FOLD_ALPHA = 0.4
NODE_MOTION_SCALE = 0.02   # of the tree's size: how far a node looks for tracks to follow


@dataclass
class Skeleton2D:
    """A binary tree of 2D nodes moving over the clip.

    ``parents (N,)`` int32, -1 for the root (node 0, the trunk base); ``nodes2d (F, N, 2)``
    float32 pixels in frame-1 coordinates; ``level (N,)`` int32 branching order (0 on the trunk,
    +1 after every bifurcation); ``fps`` frames per second; ``kind`` "traced" or "paper";
    ``confidence (F, N)`` float32 motion confidence in [0, 1) (:mod:`.node_motion`; None: not
    measured); ``times (F,)`` seconds from the first frame (None: ``index / fps``);
    ``hidden_trunk`` the crown hides the trunk (it was drawn, not traced: its pixels are foliage);
    ``limbs_seen`` the trace found bark in the crown (False: its limbs follow the motion hierarchy,
    a guess the pipeline may replace by grown ones, ``kind`` "grown": :mod:`..generate.limbs`);
    ``trunk_width_px`` frame-1 px: a wide trunk the clip's bark evidence misses (sunlit, brighter
    than its crown) as the trace measured it, its bark colour's median count over the outline's
    stem (:mod:`.frame_evidence`; NaN: not measured, branch widths come from frame 1's profiles).
    """

    parents: np.ndarray
    nodes2d: np.ndarray
    level: np.ndarray
    fps: float
    kind: str = "traced"
    warnings: list[str] = field(default_factory=list)
    confidence: np.ndarray | None = None
    times: np.ndarray | None = None
    hidden_trunk: bool = False
    limbs_seen: bool = True
    trunk_width_px: float = float("nan")

    @property
    def n_nodes(self) -> int:
        return len(self.parents)

    def edges(self) -> np.ndarray:
        """``(N-1, 2)`` (parent, child) index pairs."""
        return edges_of(self.parents)


def binarize(parents: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Turn every node with k > 2 children into a chain of binary splits.

    ``pos (N, 2)``. The node keeps its nearest child; the others hang from a new node placed a
    quarter of the way toward the nearest of them, repeated until every node has ≤ 2 children.
    Returns new ``(parents, pos)``; original nodes keep their indices, new ones are appended.
    """
    par = [int(p) for p in parents]
    pts = [np.asarray(p, float) for p in pos]
    ch = children_lists(np.array(par))
    stack = list(range(len(par)))
    while stack:
        u = stack.pop()
        kids = ch[u] if u < len(ch) else []
        if len(kids) <= 2:
            continue
        d = [np.linalg.norm(pts[k] - pts[u]) for k in kids]
        kids = [kids[i] for i in np.argsort(d)]
        keep, rest = kids[0], kids[1:]
        v = len(par)
        par.append(u)
        pts.append(pts[u] + 0.25 * (pts[rest[0]] - pts[u]))
        for k in rest:
            par[k] = v
        ch[u] = [keep, v]
        ch.append(rest)
        stack.append(v)
    return np.array(par, np.int32), np.array(pts)


def fold(pos: np.ndarray, parents: np.ndarray, level: np.ndarray, alpha: float = FOLD_ALPHA,
         stop_level: int | None = None) -> np.ndarray:
    """Paper's folding: root to tip, ``x'_i ← x'_i + α (x'_j − x'_i)`` with j the parent.

    Applied to nodes with ``1 <= level <= stop_level`` (default: the second-last level, so the
    finest level keeps its centroids and the skeleton does not shrink). Parents are folded first,
    so children fold toward their parent's *folded* position. ``pos (N, 2)``.
    """
    out = np.array(pos, float)
    stop = int(level.max()) - 1 if stop_level is None else stop_level
    for n in topological_order(parents):
        p = parents[n]
        if p >= 0 and 1 <= level[n] <= stop:
            out[n] += alpha * (out[p] - out[n])
    return out


def outline_base(outline: Outline) -> np.ndarray:
    """Trunk base guess: bottom-most row of the outline, at the mid-point of its extent (px)."""
    ys, xs = np.nonzero(outline.mask)
    y = ys.max()
    row = xs[ys >= y - 2]
    return np.array([0.5 * (row.min() + row.max()), float(y)])


def crown_scale(outline: Outline) -> float:
    """Tree size in px: the larger side of the outline's bounding box."""
    x0, y0, x1, y1 = outline.bbox
    return float(max(x1 - x0, y1 - y0))


def paper_skeleton(tracks: Tracks, hier: Hierarchy, outline: Outline, alpha: float = FOLD_ALPHA,
                   progress: ProgressFn | None = None) -> Skeleton2D:
    """Paper-faithful skeleton: centroids, a trunk base, folding (see module docstring)."""
    p0 = tracks.points[0]
    cent = np.array([p0[m].mean(0) if len(m) else p0.mean(0) for m in hier.members])
    # node 0: trunk base; node c+1: cluster c
    parents = np.concatenate([[-1], np.where(hier.parent < 0, 0, hier.parent + 1)]).astype(np.int32)
    cent = fold(cent, hier.parent, hier.level, alpha)   # hierarchy levels: root cluster 0 is not moved
    pos = np.vstack([outline_base(outline), cent])
    report(progress, "skeleton", 0.5)
    fixed = np.zeros(len(parents), bool)
    fixed[0] = True
    mo = follow_tracks(pos, tracks, NODE_MOTION_SCALE * crown_scale(outline), fixed)
    report(progress, "skeleton", 1.0)
    return Skeleton2D(parents, mo.nodes, branching_level(parents), tracks.fps, "paper",
                      confidence=mo.confidence, times=tracks.times)
