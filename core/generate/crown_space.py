"""Varied crowns in 3D (issue 36 part 2): seed 000's contour space driving the envelopes trees grow in.

An envelope's front outline (:func:`.envelopes.envelope_polygon`) becomes a pinned contour as an
exemplar's does (:mod:`.exemplars`: the tree's bottom B, where its outline meets the crown's
baseline R and L), resampled to :data:`COUNTS` points and divided by its height, trunk base at the
origin, ``(x, z)`` with z up: :func:`envelope_contour`. A species keeps its sources' contours
(:attr:`.species.SpeciesModel.contours`).

``--envelope-variation V`` (0..1) grows each tree in its own crown: the contour

    c' = (1 − V) c_source + V Σ_j w_j c_j,     w ~ Dirichlet(α, …, α) per tree (its seed), α = 0.3

over the contour space (:func:`contour_space`: the species' own contours, the shipped library's,
and each seen from behind, :func:`.exemplars.mirror_pinned`), scaled back to the source's height
(:func:`varied_envelope`). V = 0 is the source's envelope itself. The leaves' colour moves V of the
way to a colour drawn in the species' range (:func:`varied_leaf_colour`).
"""
from __future__ import annotations

import numpy as np

from ..envelope import Envelope
from .envelopes import envelope_from_polygon, envelope_polygon, rasterize
from .exemplars import mirror_pinned, pinned_contour

#: points of an envelope's contour: B→R, R→L, L→B (the exemplars' 200 / 1,600 / 200, a tenth)
COUNTS = (20, 160, 20)
N_CONTOUR = sum(COUNTS)
#: the Dirichlet's concentration over the contour space: below 1 a mix leans on a few contours, so
#: trees differ (at 1 every mix of 8 contours sits near their mean: width/height spread 0.03 at V = 0.6)
ALPHA = 0.3
#: raster rows an envelope's outline is traced on
ROWS = 400


def envelope_contour(env: Envelope) -> np.ndarray:
    """``(N_CONTOUR, 2)`` the pinned contour of ``env``'s front outline, ``(x, z)`` over its height
    (trunk base at the origin, z up; module docstring)."""
    poly = envelope_polygon(env)
    mask, s, base = rasterize([poly], ROWS)
    px = pinned_contour(mask, COUNTS)[0]
    xz = np.stack([(px[:, 0] - base[0]) * s, (base[1] - px[:, 1]) * s], 1)
    height = float(max(np.ptp(xz[:, 1]), 1e-9))
    xz[:, 1] -= xz[:, 1].min()
    return xz / height


def contour_space(own: list[np.ndarray] | None, library: tuple[np.ndarray, ...] = ()) -> list[np.ndarray]:
    """The contours a varied crown is mixed from: ``own`` (a species' sources'), the shipped
    library's (``library``: :func:`.species.library_contours`), and each of them seen from behind."""
    base = [np.asarray(c, np.float64) for c in (own or [])]
    base += [c for c in library if not any(np.allclose(c, o) for o in base)]
    return base + [mirror_pinned(c) for c in base]


def varied_contour(source: np.ndarray, space: list[np.ndarray], variation: float,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``(contour, weights)``: ``(1 − V) source + V Σ w_j space_j`` (module docstring), its height 1."""
    w = rng.dirichlet(np.full(len(space), ALPHA)) if space else np.zeros(0)
    mix = np.tensordot(w, np.stack(space), 1) if space else source
    c = (1.0 - variation) * source + variation * mix
    c = c - [0.0, c[:, 1].min()]
    return c / max(float(np.ptp(c[:, 1])), 1e-9), w


def varied_envelope(env: Envelope, space: list[np.ndarray], variation: float,
                    rng: np.random.Generator) -> tuple[Envelope, dict]:
    """``(envelope, info)``: ``env`` with its crown varied by ``variation`` (0: ``env`` itself) over
    ``space``, as tall as ``env``; ``info`` the weights and the width over height before → after."""
    height = float(np.max(env.z))
    source = envelope_contour(env)
    if variation <= 0 or not space:
        return env, {"variation": 0.0}
    c, w = varied_contour(source, space, float(variation), rng)
    out = envelope_from_polygon(c * height, name=f"{getattr(env, 'name', 'envelope')} varied")
    aspect = lambda q: float(np.ptp(q[:, 0]) / max(np.ptp(q[:, 1]), 1e-9))   # noqa: E731
    return out, {"variation": round(float(variation), 4), "weights": [round(float(x), 5) for x in w],
                 "width_over_height": [round(aspect(source), 4), round(aspect(c), 4)]}


def varied_leaf_colour(leaves: dict | None, variation: float, rng: np.random.Generator) -> tuple[dict | None, list]:
    """``(leaves, colour)``: the species' foliage with its colour moved ``variation`` of the way
    to a colour drawn in its range (``colour_range``: the source clusters' 10th and 90th
    percentiles, one uniform draw along it, light to dark); unchanged without a range."""
    if leaves is None:
        return None, []
    base = np.asarray(leaves["colour"], np.float64)
    rng_ = leaves.get("colour_range")
    if rng_ is None:
        return leaves, base.round(4).tolist()
    lo, hi = np.asarray(rng_, np.float64)
    target = lo + float(rng.uniform()) * (hi - lo)
    colour = np.clip(base + variation * (target - base), 0.0, 1.0)
    return dict(leaves, colour=colour.tolist()), colour.round(4).tolist()
