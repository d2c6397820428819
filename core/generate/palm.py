"""Palms as a species keeps them and grows them (issue 19, form ``palm``): one trunk with a crown
of fronds from its top. :func:`palm_info` measures a reconstructed palm (how many fronds, how
long, how far their tips drop, how far the trunk's top leans); :func:`grow_palm` builds a new one
in 3D inside an envelope — a gently curved trunk and the fronds round its top at even azimuths,
each a chain of bones that rises and droops to the source's tip angle.
"""
from __future__ import annotations

import math

import numpy as np

from ..envelope import Envelope
from ..topology import topological_order, trunk_top

#: bones per generated frond
FROND_BONES = 6
#: a generated frond leaves the top rising at this elevation (radians) before it droops
FROND_RISE = math.radians(40.0)


def palm_info(parents: np.ndarray, rest: np.ndarray) -> dict:
    """A reconstructed palm's crown, ``rest (N, 3)`` metres (z up): ``fronds`` (tips below the
    trunk's top), ``frond_frac`` (median path length top → tip / height), ``tip_deg`` (median
    elevation of the tips seen from the top, degrees, negative: below it), ``lean`` (horizontal
    offset of the top from the base / height), ``top_frac`` (the top's height / the height)."""
    parents = np.asarray(parents)
    rest = np.asarray(rest, np.float64)
    H = max(float(rest[:, 2].max() - rest[0, 2]), 1e-9)
    t = trunk_top(parents)
    kids = np.bincount(parents[parents >= 0], minlength=len(parents))
    length = np.zeros(len(parents))
    below = np.zeros(len(parents), bool)
    below[t] = True
    for n in topological_order(parents):
        p = parents[n]
        if p >= 0 and below[p]:
            below[n] = True
            length[n] = length[p] + float(np.linalg.norm(rest[n] - rest[p]))
    tips = np.flatnonzero(below & (kids == 0))
    if len(tips) == 0:
        return {"fronds": 0, "frond_frac": 0.0, "tip_deg": 0.0, "lean": 0.0, "top_frac": 1.0}
    d = rest[tips] - rest[t]
    elev = np.degrees(np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])))
    return {"fronds": int(len(tips)), "frond_frac": float(np.median(length[tips]) / H),
            "tip_deg": float(np.median(elev)), "lean": float(np.hypot(*(rest[t, :2] - rest[0, :2])) / H),
            "top_frac": float((rest[t, 2] - rest[0, 2]) / H)}


def _frond(T: np.ndarray, L: float, e: float, kappa: float, azimuth: float) -> np.ndarray:
    """``(FROND_BONES, 3)`` points of one frond from ``T``: ``T + L (s cos e u + (s sin e − κ s²) z)``."""
    s = np.arange(1, FROND_BONES + 1) / FROND_BONES
    u = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
    return T + L * (s[:, None] * math.cos(e) * u + (s * math.sin(e) - kappa * s ** 2)[:, None] * np.array([0, 0, 1.0]))


def grow_palm(info: dict, env: Envelope, rng: np.random.Generator,
              trunk_bones: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """A new palm's ``(parents (N,), rest (N, 3))`` metres, base at the origin, inside ``env``
    (metres): ``info`` of :func:`palm_info`. Fronds: ``info["fronds"]`` (±1), each
    ``frond_frac`` of the tree's height long along its bones (±10 %), at even azimuths (jittered), rising at
    :data:`FROND_RISE` and drooping so the tip is seen at ``tip_deg`` from the top:
    ``p(s) = T + L (s cos e u + (s sin e − κ s²) z)``, ``κ = sin e − sin(tip)``. The trunk follows
    Ω's axis up to ``T`` at ``top_frac`` of Ω's height (at most its top less the fronds' rise);
    fronds that would leave Ω are
    shortened (by 10 % steps) until every point is inside."""
    H = float(np.max(env.z))
    n_f = max(3, int(info["fronds"]) + int(rng.integers(-1, 2)))
    tip = math.radians(float(np.clip(info["tip_deg"], -80.0, 30.0)))
    e = FROND_RISE
    kappa = max(math.sin(e) - math.sin(tip), 1e-3)
    s_peak = min(1.0, math.sin(e) / (2 * kappa))
    unit = np.vstack([np.zeros(3), _frond(np.zeros(3), 1.0, e, kappa, 0.0)])
    arc = float(np.linalg.norm(np.diff(unit, axis=0), axis=1).sum())          # frond length per unit L
    rise1 = max(s_peak * math.sin(e) - kappa * s_peak ** 2, 0.0)               # rise above T per unit L
    # frond_frac is a length along the frond as a share of the tree's own height, T + the rise
    top = float(info.get("top_frac", 1.0)) * H
    f = float(info["frond_frac"]) * rng.uniform(0.9, 1.1)
    L = f * top / max(arc - f * rise1, 1e-3)
    az0 = rng.uniform(0, 2 * np.pi)
    azimuths = az0 + 2 * np.pi * np.arange(n_f) / n_f + rng.normal(scale=0.15, size=n_f)
    for _ in range(30):
        top_z = min(top, H - L * rise1)
        z = np.linspace(0.0, top_z, trunk_bones + 1)
        c, _ = env.at(z)
        trunk = np.stack([c, np.zeros_like(z), z], 1)
        fronds = [_frond(trunk[-1], L, e, kappa, a) for a in azimuths]
        if env.contains(np.concatenate(fronds), tol=0.0).all() or L < 0.02 * H:
            break
        L *= 0.9
    trunk[0] = 0.0                                             # the base at the origin
    pos = [trunk] + fronds
    parents = [np.arange(-1, trunk_bones)]
    for k in range(n_f):
        first = trunk_bones + 1 + k * FROND_BONES
        parents.append(np.concatenate([[trunk_bones], np.arange(first, first + FROND_BONES - 1)]))
    return np.concatenate(parents).astype(np.int32), np.concatenate(pos)
