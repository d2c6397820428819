"""Where a trunk runs when the video does not show it all (issue 19): under a crown that hangs to
the ground (:func:`hidden_trunk`) and up a conifer to its top (:func:`leader_curve`,
:func:`leader_tip`). The traced skeleton (:mod:`.trace`) makes its paths follow them.
"""
from __future__ import annotations

import numpy as np


def hidden_trunk(mask: np.ndarray, base_width: float, share: float,
                 outline: np.ndarray | None = None) -> tuple[int, int, int, float] | None:
    """A trunk the crown hides (issue 19): when the tree's pixels ``mask (h, w)`` (frame 1's
    foreground, or the outline) are wider at 5 % of the outline's height above the outline's
    lowest row (``outline (h, w)``; ``mask``'s own when None) than ``base_width`` of their
    widest row, what stands on the ground is foliage (a trunk is a small share of its crown's
    width), so the trunk cannot be seen. (Measured at the outline's base, not the tree pixels':
    a trunk the colour test missed must not make the crown's lower edge look like the ground.)
    Returns ``(x, y, top_y, ratio)``: the base in working px at the tree's lowest point in the
    column of its pixels' median x (a crown's weight stands over its trunk), the trunk's top
    ``share`` of the height above it (no fork can be seen: a broadleaf's first fork
    is at about that share) and the width ratio measured; None when the base is narrow."""
    ref = mask if outline is None else outline
    rows = np.flatnonzero(ref.any(1))
    if len(rows) < 10 or not mask.any():
        return None
    top, bot = int(rows.min()), int(rows.max())
    width = mask.sum(1)
    ratio = float(width[int(round(bot - 0.05 * (bot - top)))] / max(width.max(), 1))
    if ratio <= base_width:
        return None
    x = int(np.median(np.nonzero(mask)[1]))                 # a crown's mass balances over its trunk
    col = np.flatnonzero(mask[:, max(x - 2, 0):x + 3].any(1))
    y = int(col.max()) if len(col) else bot
    return x, y, int(round(y - share * (y - top))), ratio


def leader_curve(ridge: np.ndarray, mask: np.ndarray, base: tuple[int, int], tip: tuple[int, int]) -> np.ndarray:
    """A conifer's leader ``(K, 2)`` working px, one point per row from the base up to the top: a
    stem bent by the wind, ``x(z) = x0 + b·z + c·z²`` (z up from the base), leaving the base along
    the trunk as the bark shows it below the crown (``b``: the strongest ``ridge`` per row where the
    outline ``mask`` is narrow, a line fitted through them; straight to the top when fewer than 10
    rows show it) and
    reaching ``tip`` (``c``). A trunk that leans straight gives a line, one that bends a curve."""
    bx, by = base
    L = max(by - tip[1], 1)
    width = mask.sum(1)
    rows = np.arange(by, tip[1] - 1, -1)
    stem = [y for y in rows if width[y] <= 0.2 * width.max()][: max(10, L // 4)]
    b = (tip[0] - bx) / float(L)                             # no trunk seen: straight to the top
    if len(stem) >= 10:
        xs = []
        half = max(2, int(0.03 * L))                          # the trunk's neighbourhood
        for y in stem:
            lo, hi = max(bx - half, 0), min(bx + half + 1, mask.shape[1])
            xs.append(lo + int(np.argmax(ridge[y, lo:hi] * mask[y, lo:hi])))
        z = by - np.array(stem, float)
        b = float(np.polyfit(z, np.array(xs, float), 1)[0]) if np.ptp(z) > 0 else 0.0
    c = (tip[0] - bx - b * L) / float(L * L)
    z = by - rows.astype(float)
    return np.stack([bx + b * z + c * z * z, rows.astype(float)], 1)


def leader_tip(mask: np.ndarray, base_x: int) -> tuple[int, int]:
    """A conifer's top (x, y) working px: the highest row of the tree's pixels ``mask (h, w)``,
    at its pixel nearest the column ``base_x`` of the trunk's base."""
    rows = np.flatnonzero(mask.any(1))
    y = int(rows.min())
    xs = np.flatnonzero(mask[y])
    return int(xs[np.argmin(np.abs(xs - base_x))]), y
