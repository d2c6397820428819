"""A photo's crown grown where the photo shows no branches, inside the predicted 3D crown (issue 35,
seed 003: space colonization fills the crown the network's dual depth bounds).

1. **Gaps**: the crown's pixels (the outline, over frame 1's tree pixels where known, above the
   trunk's first fork) farther than :data:`GAP_FRAC` of the tree's height from every traced branch.
   Under :data:`MIN_GAP` of the crown in gaps, nothing is grown.
2. **Attraction points** in them: :data:`POINTS` pixels drawn uniformly, each given a depth from
   the predicted crown there (:mod:`..reconstruct.learned_depth`): ``y`` uniform in ±``h`` with
   ``h = min(reach, interval / 2)`` (the crown's reach from the trunk's plane, its front-to-back
   interval centred on the plane: the seed's dual depth), at least :data:`MIN_HALF` of the height.
3. **Space colonization** in 3D (:func:`.colonize.colonize`, Runions et al. Eq. 1) from the lifted
   skeleton's nodes above the trunk, the step its median bone (within :data:`STEP_FRAC` of the
   height), influence :data:`INFLUENCE_FRAC` of the height, kill :data:`KILL_STEPS` steps, a slight
   upward pull; a new node must stay over the outline and within the predicted reach (+
   :data:`REACH_SLACK` of the height). At most one node per ``KILL_STEPS · step²`` of gap is added
   (the spacing colonization leaves), and at most :data:`MAX_ADDED`.

Units: the lift's, pixels from the trunk base (x right, y depth, z up); ``base_px`` where the base
is in frame 1.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..reconstruct.learned_depth import DepthImages, tree_height_px
from ..topology import trunk_chain
from ..tree3d import plane_to_image
from .colonize import colonize

# the step's bounds, the points' reach and kill distance: as a video's grown limbs (limbs.py)
from .limbs import INFLUENCE_FRAC, KILL_STEPS, STEP_FRAC

#: a crown pixel this far (share of the height) from every traced branch is a gap
GAP_FRAC = 0.08
#: under this share of the crown in gaps nothing is grown
MIN_GAP = 0.05
#: attraction points drawn in the gaps
POINTS = 800
#: the half-depth of the crown a point is drawn in is at least this share of the height
MIN_HALF = 0.02
#: upward pull (w_up of the colonization)
UP = 0.2
#: a grown node may lie this share of the height beyond the predicted reach
REACH_SLACK = 0.05
#: grown nodes: enough to cover the gaps at one node per ``KILL_STEPS · step²`` of them, at most
#: this many
MAX_ADDED = 400


@dataclass
class CrownFill:
    """``parents (N',)`` and ``rest (N', 3)`` px with the grown nodes appended (parents first);
    ``added`` nodes grown; ``gap_share`` of the crown in gaps; ``left`` attraction points never
    reached; ``stopped`` why the growth ended ("" when nothing was grown)."""

    parents: np.ndarray
    rest: np.ndarray
    added: int
    gap_share: float
    left: int
    stopped: str = ""

    def meta(self) -> dict:
        return {"added": int(self.added), "gap_share": round(float(self.gap_share), 4), "left": int(self.left),
                "stopped": self.stopped}


def crown_gaps(parents: np.ndarray, nodes2d: np.ndarray, mask: np.ndarray, tree_px: np.ndarray | None,
               height: float) -> tuple[np.ndarray, np.ndarray]:
    """``(crown, gap)`` ``(H, W)`` bool: the crown's pixels above the first fork and those farther
    than :data:`GAP_FRAC` · ``height`` from every drawn branch of the skeleton ``nodes2d (N, 2)``."""
    h, w = mask.shape
    drawn = np.full((h, w), 255, np.uint8)
    child = np.flatnonzero(np.asarray(parents) >= 0)
    seg = np.round(np.stack([nodes2d[parents[child]], nodes2d[child]], 1)).astype(np.int32)
    cv2.polylines(drawn, list(seg), False, 0, 1)
    dist = cv2.distanceTransform(drawn, cv2.DIST_L2, 5)
    crown = mask.astype(bool) & (tree_px.astype(bool) if tree_px is not None else True)
    fork_y = float(nodes2d[trunk_chain(parents)[-1], 1])
    crown[int(np.clip(np.ceil(fork_y), 0, h)):] = False
    return crown, crown & (dist > GAP_FRAC * height)


def fill_crown(parents: np.ndarray, rest: np.ndarray, base_px: np.ndarray, depth: DepthImages, mask: np.ndarray,
               tree_px: np.ndarray | None = None, seed: int = 0) -> CrownFill:
    """The lifted skeleton ``parents``, ``rest (N, 3)`` px grown into its crown's gaps (module
    docstring); unchanged (``added`` 0) when the gaps are under :data:`MIN_GAP` of the crown."""
    parents = np.asarray(parents, np.int64)
    rest = np.asarray(rest, np.float64)
    base = np.asarray(base_px, np.float64)
    H = tree_height_px(mask)
    nodes2d = plane_to_image(rest, base)
    crown, gap = crown_gaps(parents, nodes2d, mask, tree_px, H)
    share = float(gap.sum()) / max(float(crown.sum()), 1.0)
    if share < MIN_GAP or gap.sum() < 16:
        return CrownFill(parents, rest, 0, share, 0)
    rng = np.random.default_rng(seed)
    ys, xs = np.nonzero(gap)
    pick = rng.choice(len(xs), size=min(POINTS, len(xs)), replace=False)
    px = np.stack([xs[pick], ys[pick]], 1) + rng.uniform(-0.5, 0.5, (len(pick), 2))
    reach = depth.sample(depth.reach, px) * H
    half = np.maximum(np.minimum(reach, 0.5 * depth.sample(depth.interval, px) * H), MIN_HALF * H)
    pts = np.stack([px[:, 0] - base[0], rng.uniform(-1.0, 1.0, len(px)) * half, base[1] - px[:, 1]], 1)

    def inside(p: np.ndarray) -> np.ndarray:
        q = plane_to_image(p, base)
        col = np.round(q[:, 0]).astype(np.int64)
        row = np.round(q[:, 1]).astype(np.int64)
        ok = (col >= 0) & (col < mask.shape[1]) & (row >= 0) & (row < mask.shape[0])
        over = np.zeros(len(p), bool)
        over[ok] = mask[row[ok], col[ok]]
        limit = depth.sample(depth.reach, q) * H + REACH_SLACK * H
        return over & (np.abs(p[:, 1]) <= limit)

    child = np.flatnonzero(parents >= 0)
    bone = np.linalg.norm(rest[child] - rest[parents[child]], axis=1)
    step = float(np.clip(np.median(bone) if len(bone) else STEP_FRAC[0] * H, STEP_FRAC[0] * H, STEP_FRAC[1] * H))
    growing = np.ones(len(parents), bool)
    growing[trunk_chain(parents)[:-1]] = False                       # not from the trunk below the crown
    budget = len(parents) + int(min(float(gap.sum()) / (KILL_STEPS * step * step), MAX_ADDED))
    c = colonize(parents, rest, growing, pts, step, INFLUENCE_FRAC * H, KILL_STEPS * step, UP, budget,
                 inside=inside)
    return CrownFill(c.parents, c.pos, int(len(c.parents) - len(parents)), share, c.left, c.stopped)
