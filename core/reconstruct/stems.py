"""Where a trunk runs when the video does not show it all (issue 19): under a crown that hangs to
the ground (:func:`hidden_trunk`) and up a conifer to its top (:func:`leader_curve`,
:func:`leader_tip`). The traced skeleton (:mod:`.trace`) makes its paths follow them.
"""
from __future__ import annotations

import numpy as np

from ..topology import children_lists, subtree_masks, subtree_sizes, without_nodes


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


def main_stem(parents: np.ndarray, pos: np.ndarray, max_lean_deg: float = 45.0) -> np.ndarray:
    """``(K,)`` node indices from the root up the child with the most nodes under it, while each
    edge rises within ``max_lean_deg`` of the vertical (``pos (N, 2)`` image px, y down): the
    trunk and the leader it continues into."""
    kids = children_lists(parents)
    size = subtree_sizes(parents)
    out, n = [0], 0
    tan = np.tan(np.radians(max_lean_deg))
    while kids[n]:
        c = max(kids[n], key=lambda k: size[k])
        dx, dy = pos[c] - pos[n]
        if dy >= 0 or abs(dx) > tan * -dy:
            break
        out.append(c)
        n = c
    return np.asarray(out, np.int64)


def local_line(y: np.ndarray, x: np.ndarray, at: np.ndarray, sigma: float) -> np.ndarray:
    """``x`` at the heights ``at (Q,)`` on the line ``x = a + b·y`` fitted to ``(y, x) (K,)`` by least
    squares weighted by a Gaussian of ``sigma`` in ``y`` about each query (a constant when the
    weighted points span no height)."""
    w = np.exp(-0.5 * ((np.asarray(at, float)[:, None] - y[None, :]) / sigma) ** 2) + 1e-12     # (Q, K)
    sw, swy, swyy = w.sum(1), w @ y, w @ (y * y)
    swx, swxy = w @ x, w @ (x * y)
    det = sw * swyy - swy * swy
    ok = det > 1e-9 * np.maximum(sw * swyy, 1.0)
    b = np.where(ok, (sw * swxy - swy * swx) / np.where(ok, det, 1.0), 0.0)
    return (swx - b * swy) / sw + b * np.asarray(at, float)


def ridge_middles(ridge: np.ndarray, xy: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """The trunk's middle row by row along the polyline ``xy (K, 2)`` px (rising: y falls): in each
    row it spans, the column of ``ridge (h, w)``'s strongest response within half the trunk's
    ``width`` of the polyline, in the rows where that response is positive and at least a fifth
    of the rows' 90th percentile (where leaves hide the trunk, no row votes). Returns
    ``(y (R,), x (R,))`` px."""
    rows = np.arange(int(np.ceil(xy[-1, 1])), int(np.floor(xy[0, 1])) + 1)
    rows = rows[(rows >= 0) & (rows < ridge.shape[0])]
    if len(rows) == 0:
        return rows.astype(float), rows.astype(float)
    cx = np.interp(rows, xy[::-1, 1], xy[::-1, 0])
    half = max(int(round(0.5 * width)), 1)
    cols = np.clip(np.round(cx).astype(int)[:, None] + np.arange(-half, half + 1)[None], 0, ridge.shape[1] - 1)
    resp = ridge[rows[:, None], cols]                                  # (R, 2·half + 1)
    best = cols[np.arange(len(rows)), np.argmax(resp, axis=1)]
    peak = resp.max(axis=1)
    seen = peak > max(0.2 * float(np.percentile(peak, 90)), 0.0)          # rows the trunk shows in
    return rows[seen].astype(float), best[seen].astype(float)


def straighten_stem(parents: np.ndarray, pos: np.ndarray, width: float, mask: np.ndarray,
                    ridge: np.ndarray | None = None, narrow: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """A wide trunk's trace straightened across itself: ``pos (N, 2)`` px of ``mask (h, w)`` (the
    outline, y down). The trunk — the main stem (:func:`main_stem`) from the root through the rows
    where the outline is at most ``narrow`` of its widest — gets a line ``x(y)``, least squares
    weighted by a Gaussian in ``y`` of σ = 3 ``width`` (a trunk that bends over several of its
    widths keeps its bend), through the trunk's ``ridge`` (the ridge at its own scale, which peaks
    at its middle: :func:`ridge_middles`, row by row) or, without one, through the nodes. The
    stem's next nodes up that lie within half the trunk's ``width`` of the line join it (the trunk
    seen on up through the crown), and every trunk node moves sideways onto the line, by at most
    half the ``width``. A side branch off the trunk that never leaves it (every node of its
    subtree within 0.75 ``width`` of the line, its edge and the line's own error, in the trunk's
    rows) is dropped: it is a second path up the same wide bark, drawn as a stub along the trunk.
    A trace up a trunk 40 px wide wanders from edge to edge of it (the real cedar's: 16 px sideways
    over 30 px up at its foot, and the whole foot a quarter of the width right of the middle), and a
    tube drawn along it kinks where the photo's trunk is straight. The stem's bend into the crown
    is neither moved nor fitted. Returns new ``(parents, pos)`` (kept nodes in their order)."""
    out = np.array(pos, np.float64, copy=True)
    parents = np.asarray(parents)
    if not np.isfinite(width) or width <= 0 or not mask.any():
        return parents, out
    stem = main_stem(parents, out)
    span = mask.sum(1)
    row = np.clip(np.round(out[stem, 1]).astype(int), 0, mask.shape[0] - 1)
    bare = span[row] <= narrow * span.max()
    k = int(np.argmin(bare)) if not bare.all() else len(stem)        # the bare prefix from the root
    if k < 2:
        return parents, out
    sigma = 3.0 * width

    def data(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if ridge is None:
            return out[nodes, 1], out[nodes, 0]
        return ridge_middles(ridge, out[nodes], width)

    if k < len(stem):                                                 # on up the straight trunk
        yd, xd = data(stem[:k])
        ahead = local_line(yd, xd, out[stem[k:], 1], sigma)
        off = np.abs(out[stem[k:], 0] - ahead) > 0.5 * width
        k += int(np.argmax(off)) if off.any() else len(off)
    stem = stem[:k]
    if len(stem) < 3:
        return parents, out
    y = out[stem, 1]
    yd, xd = data(stem)
    if len(yd) < 3:
        return parents, out
    fit = local_line(yd, xd, y, sigma)
    out[stem, 0] += np.clip(fit - out[stem, 0], -0.5 * width, 0.5 * width)
    # side branches that stay on the bark: every node within 0.75 width of the line, in its rows
    line_x = np.interp(out[:, 1], y[::-1], out[stem, 0][::-1])      # the stem rises: y falls along it
    inside = (out[:, 1] <= y[0]) & (out[:, 1] >= y[-1]) & (np.abs(out[:, 0] - line_x) <= 0.75 * width)
    on_stem = np.zeros(len(parents), bool)
    on_stem[stem] = True
    starts = np.flatnonzero(~on_stem & (parents >= 0))
    starts = starts[on_stem[parents[starts]]]
    if len(starts):
        subs = subtree_masks(parents, starts)                                       # (S, N)
        drop = subs[(subs <= inside[None]).all(1)].any(0)
        if drop.any():
            keep, parents, _ = without_nodes(parents, drop)
            out = out[keep]
    return parents, out
