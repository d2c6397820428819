"""How far a grown tree sways (:func:`.growth.grow_tree`, step 4): as far as its species' source
did (:func:`match_excursion`), and no farther than the drawn envelope holds (:func:`contain_sway`)."""
from __future__ import annotations

import numpy as np

from .envelopes import Region2D
from .species import sway_excursion
from .sway import forward_kinematics

#: the swaying crown stays in its envelope: at most this share of the node-frames that start inside
#: may leave it by more than ``SWAY_SLACK`` × the tree's height
SWAY_OUTSIDE = 0.005
#: ... and in no frame more than this share of them
SWAY_OUTSIDE_FRAME = 0.02
SWAY_SLACK = 0.02


def match_excursion(parents: np.ndarray, rest: np.ndarray, rot: np.ndarray, target: float | None) -> float:
    """The factor on the sampled sway ``rot (F, N, 3)`` (radians, about ``rest (N, 3)`` metres) that
    makes the tree's :func:`~.species.sway_excursion` the source's ``target`` (share of the height;
    None or 0: 1). The spectra give each node its own amplitude and phase, but how much of the
    sway adds up along a chain of bones depends on how the source's motion was split between
    neighbouring bones; the excursion is what a viewer compares. Two secant steps (forward
    kinematics is nearly linear in the factor at these angles), within [1/4, 4]."""
    if not target or target <= 0:
        return 1.0
    H = float(max(rest[:, 2].max(), 1e-6))
    factor = 1.0
    for _ in range(2):
        got = sway_excursion(forward_kinematics(parents, rest, rot * factor), H)
        if got <= 1e-12:
            return 1.0
        factor = float(np.clip(factor * target / got, 0.25, 4.0))
    return factor


def contain_sway(parents: np.ndarray, rest: np.ndarray, rot: np.ndarray, region: Region2D) -> tuple[np.ndarray, float]:
    """Forward kinematics of the sway ``rot (F, N, 3)`` about ``rest (N, 3)`` metres, with the
    rotations scaled down by one factor for the tree (bisection, 6 steps) where the sway would carry
    more than :data:`SWAY_OUTSIDE` of the node-frames (or :data:`SWAY_OUTSIDE_FRAME` of the nodes in
    one frame) more than :data:`SWAY_SLACK` of the height outside the envelope ``region`` (x, z:
    the picture plane, where the artist drew it; in depth Ω is only a surface of revolution of that
    drawing, and holding the sway to it took a quarter of a species' sway) — the species' own sway
    fits the artist's silhouette (the wind
    strength scales it on top). Returns ``(nodes3d (F, N, 3), factor)``; the factor is 1 for a sway
    that stays inside."""
    import cv2
    H = float(max(rest[:, 2].max(), 1e-6))
    grow_px = int(np.ceil(SWAY_SLACK * H / region.cell))
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * grow_px + 1,) * 2)   # slack in every direction
    near = cv2.dilate(region.full.astype(np.uint8), disk).astype(bool)

    def inside(p: np.ndarray) -> np.ndarray:
        return region.sample(near, p[..., [0, 2]])

    start = inside(rest)

    def contained(nodes: np.ndarray) -> bool:
        if not start.any():
            return True
        per_frame = (~inside(nodes[:, start])).mean(axis=1)
        return bool(per_frame.mean() <= SWAY_OUTSIDE and per_frame.max() <= SWAY_OUTSIDE_FRAME)

    nodes3d = forward_kinematics(parents, rest, rot)
    if contained(nodes3d):
        return nodes3d, 1.0
    lo, hi, best = 0.0, 1.0, None
    for _ in range(6):
        mid = 0.5 * (lo + hi)
        cand = forward_kinematics(parents, rest, rot * mid)
        if contained(cand):
            lo, best = mid, cand
        else:
            hi = mid
    if best is None:
        return forward_kinematics(parents, rest, rot * 0.0), 0.0
    return best, lo
