"""The species model of paper §5.2 (:class:`SpeciesModel`): Dirichlets of the bifurcations'
angle and length ratios and of the motion spectra per axis (:mod:`.features`), log-normal
rotation sizes with a trend in depth, branch orientations and foliage; :func:`fit_species` from a
reconstructed tree, and the human-readable JSON species files (the shipped library in
``species/``).
"""
from __future__ import annotations

import functools
import json
import math
import os
import tempfile
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..detail.grown_leaves import envelope_cover
from ..envelope import envelope_from_meta
from ..errors import InputError
from ..forms import form_of
from .crown_space import N_CONTOUR, envelope_contour
from .dirichlet import fit_dirichlet
from .envelopes import envelope_from_polygon
from .features import (
    KEEP_FRACTION,
    SpectralFeatures,
    anchor_links,
    bifurcation_features,
    node_rotations,
    shift_tuple,
    spectral_features,
    spectrum_peaks,
)
from .palm import palm_info

FORMAT = "tree_from_video.species"
VERSION = 1
AXES = ("x", "y", "z")


# ============================================================================ species model

@dataclass
class AxisMotion:
    """Motion model for one rotation axis. ``energy`` Dirichlet α ``(K,)`` of the energy ratios
    (which frequencies dominate); ``real`` / ``imag`` Dirichlet α ``(K+1,)`` of the shifted
    real/imaginary tuples (the phases between the bins); ``freqs_hz (K,)`` of the kept bins;
    ``log_rms = (a, b, σ)``: ``log rms ~ N(a + b·ρ, σ²)`` (rms radians, ρ the node's normalized
    depth); ``phase_spread`` radians (circular std of the node phases at the dominant bin);
    ``rms_max`` radians, the largest per-bone rms of the source (a sampled bone never sways more:
    the log-normal's tail, extrapolated along a steep depth slope, reached 0.87 rad where the
    source's bones reach 0.085); None in files fitted before it was kept."""

    energy: np.ndarray
    real: np.ndarray
    imag: np.ndarray
    freqs_hz: np.ndarray
    log_rms: tuple
    phase_spread: float
    fallback: str | None = None
    rms_max: float | None = None

    @property
    def dominant_hz(self) -> float:
        """Frequency (Hz) of the largest mean energy ratio."""
        return float(self.freqs_hz[int(np.argmax(self.energy))])

    def peaks_hz(self, n_peaks: int = 2) -> np.ndarray:
        """The ``n_peaks`` highest peaks (Hz, ascending) of the mean energy ratios."""
        return self.freqs_hz[spectrum_peaks(self.energy / self.energy.sum(), n_peaks)]


@dataclass
class SpeciesModel:
    """Everything needed to grow and animate trees like one example (paper §5).

    ``angles``/``lengths``: Dirichlet α ``(3,)`` of ⟨θ1:θ2:θ3⟩ and ⟨L1:L2:L3⟩; ``motion``: one
    :class:`AxisMotion` per axis x, y, z; ``trunk_frac``: trunk (base → first bifurcation) as a
    share of the height; ``segment_frac``: median bone length as a share of the height (how finely
    branches are subdivided); ``segments_per_branch`` median; ``min_branch_frac`` 5th-percentile
    branch chord / height (growth stops below it); ``branch_frac`` median branch chord / height
    (the scale of the first branches above the trunk); ``n_bifurcations`` in the source;
    ``orientation_deg = (mean, std)`` of the branches' angle from the vertical in the picture
    plane (branch chords above the trunk; growth uses it as a tropism term); ``mirror_p`` share
    of clockwise (mirrored) bifurcations;
    ``source_height_m``; ``fps`` and ``n_frames`` of the source; ``conifer``; ``form``
    (:data:`..forms.TREE_FORMS`) and, for a palm, ``palm`` (:func:`.palm.palm_info`); ``mu_deg`` mean
    branching angle of the source lift; ``fallbacks`` notes from degenerate fits; ``leaves`` the
    source's foliage (median leaf colour sRGB, cluster radius / height, cards per cluster,
    clusters per thin-branch node, and ``fill`` the share of its envelope's front view they cover)
    or None for a bare source; ``sway_excursion`` how far the source's
    nodes sway (:func:`sway_excursion`, a share of the height; None in files fitted before it was
    measured), which generated trees are scaled to at wind 1; ``widths`` ``(trunk, tip)`` the
    source's trunk-base and median tip radius as shares of its height (None in older files:
    generated trees then take :class:`..growth.GrowParams`' defaults); ``contours`` the sources'
    crown contours (:func:`.crown_space.envelope_contour`: ``(N_CONTOUR, 2)`` (x, z) over the height,
    pinned; none in files fitted before them), what ``--envelope-variation`` mixes; ``bark_dir`` the
    folder of the source's bark from photos (:func:`..detail.bark_photo.write_bark_files`; the file
    keeps it relative to itself), which trees grown from it take; None: the procedural bark."""

    name: str
    angles: np.ndarray
    lengths: np.ndarray
    motion: list
    trunk_frac: float
    segment_frac: float
    segments_per_branch: float
    min_branch_frac: float
    branch_frac: float
    n_bifurcations: int
    orientation_deg: tuple
    mirror_p: float
    source_height_m: float
    fps: float
    n_frames: int
    conifer: bool = False
    mu_deg: float = 38.0
    version: int = VERSION
    fallbacks: list = field(default_factory=list)
    leaves: dict | None = None      # {"colour": sRGB (3,), "radius_frac", "cards", "per_node"} or None
    sway_excursion: float | None = None   # the source's sway (:func:`sway_excursion`); None: not measured
    widths: tuple | None = None           # (trunk, tip) radius / height (:func:`branch_widths`); None: not measured
    form: str = "broadleaf"               # forms.TREE_FORMS; files before forms: from ``conifer``
    palm: dict | None = None              # a palm's crown (palm.palm_info); None for other forms
    contours: list = field(default_factory=list)   # the sources' crown contours (crown_space), (200, 2) each
    bark_dir: str | None = None           # the folder of the source's bark maps (bark_photo), None: procedural

    def to_json(self) -> dict:
        """JSON-able dict (rounded, human-readable)."""
        def arr(a, d=6):
            return [float(f"{x:.{d}g}") for x in np.asarray(a, float)]
        return {
            "format": FORMAT, "version": VERSION, "name": self.name,
            "conifer": bool(self.conifer), "form": self.form,
            **({} if self.palm is None else {"palm": {k: (round(float(v), 5) if isinstance(v, float) else v)
                                                      for k, v in self.palm.items()}}),
            "shape": {"angle_alpha": arr(self.angles), "length_alpha": arr(self.lengths),
                      "trunk_frac": round(float(self.trunk_frac), 5),
                      "segment_frac": round(float(self.segment_frac), 5),
                      "segments_per_branch": round(float(self.segments_per_branch), 3),
                      "min_branch_frac": round(float(self.min_branch_frac), 5),
                      "branch_frac": round(float(self.branch_frac), 5),
                      "orientation_deg": [round(float(x), 3) for x in self.orientation_deg],
                      "mirror_p": round(float(self.mirror_p), 4),
                      "n_bifurcations": int(self.n_bifurcations), "mu_deg": round(float(self.mu_deg), 3),
                      **({} if self.widths is None else
                         {"trunk_radius_frac": round(float(self.widths[0]), 6),
                          "tip_radius_frac": round(float(self.widths[1]), 6)})},
            "motion": {AXES[a]: {"freqs_hz": arr(m.freqs_hz, 5), "energy_alpha": arr(m.energy),
                                 "real_alpha": arr(m.real), "imag_alpha": arr(m.imag),
                                 "log_rms": arr(m.log_rms), "phase_spread": round(float(m.phase_spread), 5),
                                 **({} if m.rms_max is None else {"rms_max": float(f"{m.rms_max:.6g}")})}
                       for a, m in enumerate(self.motion)},
            "source": {"height_m": round(float(self.source_height_m), 4), "fps": float(self.fps),
                       "n_frames": int(self.n_frames),
                       **({} if self.sway_excursion is None else {"sway_excursion": round(float(self.sway_excursion), 6)})},
            "fallbacks": list(self.fallbacks),
            **({"leaves": {"colour": arr(self.leaves["colour"], 4),
                           "radius_frac": round(float(self.leaves["radius_frac"]), 5),
                           "cards": int(self.leaves["cards"]),
                           "per_node": round(float(self.leaves["per_node"]), 4),
                           **({"fill": round(float(self.leaves["fill"]), 4)} if "fill" in self.leaves else {}),
                           **({"colour_range": np.asarray(self.leaves["colour_range"], float).round(4).tolist()}
                              if self.leaves.get("colour_range") is not None else {})}}
               if self.leaves else {}),
            **({"crown_contours": [np.asarray(c, float).round(4).tolist() for c in self.contours]}
               if self.contours else {}),
            **({"bark": {"dir": self.bark_dir}} if self.bark_dir else {}),
        }

    @classmethod
    def from_json(cls, d: dict, where: str = "species file") -> "SpeciesModel":
        """Parse :meth:`to_json` output; :class:`InputError` naming the problem otherwise."""
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise InputError(f"{where} is not a Tree from Video species file (no \"format\": \"{FORMAT}\"); "
                             "pick a .json written by Fit Species")
        ver = d.get("version")
        if not isinstance(ver, int) or ver > VERSION:
            raise InputError(f"{where} has version {ver!r}, newer than this add-on reads ({VERSION}); "
                             "update the add-on")
        if ver < 1:
            raise InputError(f"{where} has an old version {ver!r}; fit the species again from its tree")
        try:
            sh, mo, src = d["shape"], d["motion"], d["source"]

            def alpha(x, n=None):
                a = np.asarray(x, np.float64)
                if a.ndim != 1 or (n and len(a) != n) or len(a) < 2 or not np.all(np.isfinite(a)) or (a <= 0).any():
                    raise ValueError("Dirichlet parameters must be positive numbers")
                return a
            motion = []
            for ax in AXES:
                m = mo[ax]
                freqs = np.asarray(m["freqs_hz"], np.float64)
                K = len(freqs)
                energy = alpha(m["energy_alpha"], K)
                real, imag = alpha(m["real_alpha"], K + 1), alpha(m["imag_alpha"], K + 1)
                lr = tuple(float(x) for x in m["log_rms"])
                if len(lr) != 3 or not all(math.isfinite(x) for x in lr) or not np.all(freqs > 0):
                    raise ValueError("log_rms must be three numbers and frequencies positive")
                rms_max = None if m.get("rms_max") is None else float(m["rms_max"])
                if rms_max is not None and not (math.isfinite(rms_max) and rms_max > 0):
                    raise ValueError("rms_max must be a positive number")
                motion.append(AxisMotion(energy, real, imag, freqs, lr, float(m["phase_spread"]), rms_max=rms_max))
            model = cls(str(d.get("name", "species")), alpha(sh["angle_alpha"], 3), alpha(sh["length_alpha"], 3),
                        motion, float(sh["trunk_frac"]), float(sh["segment_frac"]),
                        float(sh["segments_per_branch"]), float(sh["min_branch_frac"]),
                        float(sh["branch_frac"]), int(sh["n_bifurcations"]),
                        _orientation(sh["orientation_deg"]), float(np.clip(float(sh["mirror_p"]), 0.0, 1.0)),
                        float(src["height_m"]), float(src["fps"]),
                        int(src["n_frames"]), bool(d.get("conifer", False)), float(sh.get("mu_deg", 38.0)),
                        ver, list(d.get("fallbacks", [])), _leaf_info(d.get("leaves")),
                        None if src.get("sway_excursion") is None else float(src["sway_excursion"]),
                        _widths(sh), form_of(bool(d.get("conifer", False)), d.get("form")),
                        _palm(d.get("palm")), _contours(d.get("crown_contours")),
                        str(d["bark"]["dir"]) if isinstance(d.get("bark"), dict) and d["bark"].get("dir") else None)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{where} is incomplete or damaged ({exc.__class__.__name__}: {exc}); "
                             "fit the species again or pick another file") from None
        if not (0 < model.trunk_frac < 1 and 0 < model.segment_frac < 1 and 0 < model.branch_frac < 1
                and 0 < model.min_branch_frac < 1 and model.fps > 0):
            raise InputError(f"{where} has out-of-range shape numbers; fit the species again")
        return model


def _contours(d) -> list:
    """The ``crown_contours`` of a species file: a list of ``(N_CONTOUR, 2)`` arrays."""
    out = []
    for c in d or []:
        a = np.asarray(c, np.float64)
        if a.shape != (N_CONTOUR, 2) or not np.all(np.isfinite(a)):
            raise ValueError(f"a crown contour must be {N_CONTOUR} (x, z) pairs")
        out.append(a)
    return out


def _palm(d) -> dict | None:
    if d is None:
        return None
    info = {"fronds": int(d["fronds"]), "frond_frac": float(d["frond_frac"]), "tip_deg": float(d["tip_deg"]),
            "lean": float(d.get("lean", 0.0)), "top_frac": float(d.get("top_frac", 1.0))}
    if info["fronds"] < 1 or not 0 < info["frond_frac"] < 2:
        raise ValueError("a palm needs fronds >= 1 and 0 < frond_frac < 2")
    return info


def _widths(sh: dict) -> tuple[float, float] | None:
    if sh.get("trunk_radius_frac") is None:
        return None
    w = (float(sh["trunk_radius_frac"]), float(sh["tip_radius_frac"]))
    if not 0 < w[1] <= w[0] < 1:
        raise ValueError("branch widths need 0 < tip_radius_frac <= trunk_radius_frac < 1")
    return w


def _leaf_info(d) -> dict | None:
    if d is None:
        return None
    colour = [float(c) for c in d["colour"]]
    info: dict[str, Any] = {"colour": colour, "radius_frac": float(d["radius_frac"]), "cards": int(d["cards"]),
            "per_node": float(d["per_node"])}
    if d.get("colour_range") is not None:
        rng_ = np.asarray(d["colour_range"], np.float64)
        if rng_.shape != (2, 3) or not np.all((rng_ >= 0) & (rng_ <= 1)):
            raise ValueError("leaves' colour_range must be two sRGB colours 0..1")
        info["colour_range"] = rng_.tolist()
    if d.get("fill") is not None:
        info["fill"] = float(d["fill"])
        if not 0 < info["fill"] <= 1:
            raise ValueError("leaves' fill must be in (0, 1]")
    if len(colour) != 3 or not all(0 <= c <= 1 for c in colour) or not 0 < info["radius_frac"] < 1 \
            or not 1 <= info["cards"] <= 256 or not info["per_node"] > 0:
        raise ValueError("leaves need colour (3 values 0..1), 0 < radius_frac < 1, cards 1..256, per_node > 0")
    return info


def leaf_info(tree) -> dict | None:
    """The foliage of a reconstructed tree as a species keeps it (see :class:`SpeciesModel`); with
    ``"fill"``, the share of its envelope's front view its leaves cover, when it has an envelope."""
    lv = getattr(tree, "leaves", None)
    if lv is None or lv.count == 0:
        return None
    H = float(max(np.ptp(tree.nodes3d[0][:, 2]), 1e-6))
    r = np.asarray(tree.radius, np.float64)
    thin = int(np.sum(r < 0.3 * r.max())) or 1
    info = {"colour": np.median(lv.colour, axis=0).tolist(), "radius_frac": float(lv.radius / H),
            "cards": int(lv.cards), "per_node": float(lv.count / thin),
            # the clusters' colours, 10th and 90th percentiles: the range a generated tree's leaves
            # vary in (--envelope-variation)
            "colour_range": np.percentile(np.asarray(lv.colour, np.float64), [10, 90], axis=0).tolist()}
    env = envelope_from_meta(tree.meta)
    if env is not None:
        info["fill"] = envelope_cover(lv, env)
    return info


def _orientation(x) -> tuple[float, float]:
    o = tuple(float(v) for v in x)
    if len(o) != 2 or not all(math.isfinite(v) for v in o) or o[1] <= 0:
        raise ValueError("orientation_deg must be [mean, std > 0] degrees")
    return o


def branch_orientations(parents: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """``(M,)`` degrees: angle from the vertical (x, z plane) of every branch chord (anchor →
    next anchor or tip) that does not start at the root (the trunk is excluded)."""
    parents = np.asarray(parents)
    p2 = np.asarray(pos, np.float64)[:, [0, 2]] if pos.shape[1] == 3 else np.asarray(pos, np.float64)
    up, down = anchor_links(parents)
    nodes = np.flatnonzero((down == np.arange(len(parents))) & (parents >= 0) & (up >= 0))
    nodes = nodes[parents[up[nodes]] >= 0]
    v = p2[nodes] - p2[up[nodes]]
    return np.degrees(np.abs(np.arctan2(v[:, 0], v[:, 1])))


def _fit_log_rms(rms: np.ndarray, rho: np.ndarray) -> tuple[float, float, float]:
    """``log rms = a + b ρ + ε`` by least squares; ``(a, b, σ)`` (b = 0 with fewer than 3 nodes;
    σ at least 0.05)."""
    if len(rms) == 0:
        return (math.log(1e-4), 0.0, 0.05)
    y = np.log(rms)
    if len(rms) < 3 or np.ptp(rho) < 1e-9:
        return (float(y.mean()), 0.0, float(max(y.std(), 0.05)))
    A = np.stack([np.ones_like(rho), rho], 1)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    sigma = float(max(np.std(y - A @ coef), 0.05))
    return (float(coef[0]), float(coef[1]), sigma)


def fit_axis_motion(sf: SpectralFeatures) -> AxisMotion:
    """Dirichlets of the energy ratios and of the shifted real/imag tuples, and the RMS model."""
    K = len(sf.freqs_hz)
    if len(sf.u) == 0:
        return AxisMotion(np.ones(K), np.ones(K + 1), np.ones(K + 1), sf.freqs_hz, _fit_log_rms(sf.rms, sf.rho),
                          sf.phase_spread, "no moving node: uniform spectra")
    # energy ratios: mean fixed to the sample mean (so the dominant frequency of the example is
    # exactly the model's), precision by ML; real/imag tuples: full ML
    fe = fit_dirichlet(sf.energy, fixed_mean=sf.energy.mean(axis=0))
    fr, fi = fit_dirichlet(shift_tuple(sf.u)), fit_dirichlet(shift_tuple(sf.v))
    notes = [f"{n}: {f.fallback}" for n, f in (("energy", fe), ("real", fr), ("imag", fi)) if f.fallback]
    return AxisMotion(fe.alpha, fr.alpha, fi.alpha, sf.freqs_hz, _fit_log_rms(sf.rms, sf.rho), sf.phase_spread,
                      "; ".join(notes) or None, float(sf.rms.max()))


def _orientation_stats(g: np.ndarray) -> tuple[float, float]:
    """(mean, std) degrees, std at least 10°; (40, 30) with fewer than 3 branches."""
    if len(g) < 3:
        return (40.0, 30.0)
    return (float(g.mean()), float(max(g.std(), 10.0)))


def sway_excursion(nodes3d: np.ndarray, height: float) -> float:
    """How far a tree's nodes sway: the 95th percentile over nodes of the largest distance
    (over the frames) from the node's mean position, as a share of ``height``. ``nodes3d (F, N, 3)``
    metres. From the mean, not from frame 0, so a clip that starts mid-swing counts the same."""
    X = np.asarray(nodes3d, np.float64)
    if X.shape[0] < 2 or X.shape[1] == 0:
        return 0.0
    d = np.linalg.norm(X - X.mean(0, keepdims=True), axis=-1).max(0)
    return float(np.percentile(d, 95) / max(height, 1e-9))


def fit_species(tree, name: str, keep: float = KEEP_FRACTION) -> SpeciesModel:
    """Fit a :class:`SpeciesModel` to a :class:`~.tree3d.Tree3D` (metres, frame 0 = rest).

    Twigs (:func:`..detail.twigs.add_twigs`) are left out: the species is its branches'.
    Raises :class:`InputError` if the tree has no bifurcation or fewer than 8 frames."""
    from ..detail.twigs import without_twigs
    tree = without_twigs(tree)
    parents = np.asarray(tree.parents)
    nodes = np.asarray(tree.nodes3d, np.float64)
    if nodes.shape[0] < 8:
        raise InputError(f"the tree has {nodes.shape[0]} frame(s); fitting its motion needs at least 8 — "
                         "reconstruct a longer clip")
    feats = bifurcation_features(parents, nodes[0])
    if len(feats.apex) == 0:
        raise InputError("the tree has no bifurcation to learn from; reconstruct a tree with branches")
    height = float(max(np.ptp(nodes[0, :, 2]), nodes[0, :, 2].max(), 1e-6))
    form = form_of(bool(tree.meta.get("conifer", False)), tree.meta.get("form"))
    fa, fl = fit_dirichlet(feats.angles), fit_dirichlet(feats.lengths)
    fallbacks = [f"{n}: {f.fallback}" for n, f in (("angles", fa), ("lengths", fl)) if f.fallback]
    # absolute scale: trunk, bone and branch lengths as shares of the height
    from ..topology import children_lists, edges_of
    up, down = anchor_links(parents)
    root = int(np.flatnonzero(parents < 0)[0])
    kids0 = children_lists(parents)[root]
    first = int(down[kids0[0]]) if len(kids0) == 1 else root
    trunk = float(np.linalg.norm(nodes[0, first, [0, 2]] - nodes[0, root, [0, 2]]))
    e = edges_of(parents)
    bone = np.linalg.norm(nodes[0, e[:, 1]][:, [0, 2]] - nodes[0, e[:, 0]][:, [0, 2]], axis=1)
    seg_per_branch = []                     # edges between consecutive anchors/tips
    for n in np.flatnonzero((down == np.arange(len(parents))) & (parents >= 0)):
        c, k = n, 0
        while True:
            k += 1
            c = parents[c]
            if down[c] == c:
                break
        seg_per_branch.append(k)
    rot = node_rotations(parents, nodes)
    sfs = spectral_features(parents, rot, tree.fps, keep)
    motion = [fit_axis_motion(sf) for sf in sfs]
    fallbacks += [f"motion {AXES[a]}: {m.fallback}" for a, m in enumerate(motion) if m.fallback]
    return SpeciesModel(
        name=name, angles=fa.alpha, lengths=fl.alpha, motion=motion,
        trunk_frac=float(np.clip(trunk / height, 0.02, 0.9)),
        segment_frac=float(np.clip(np.median(bone) / height, 0.005, 0.5)),
        segments_per_branch=float(np.median(seg_per_branch)) if seg_per_branch else 1.0,
        min_branch_frac=float(np.clip(np.percentile(feats.chord[:, 1:], 5) / height, 0.002, 0.3)),
        branch_frac=float(np.clip(np.median(feats.chord[:, 1:]) / height, 0.005, 0.5)),
        n_bifurcations=int(len(feats.apex)),
        orientation_deg=_orientation_stats(branch_orientations(parents, nodes[0])),
        mirror_p=float(np.mean(feats.mirrored)), source_height_m=height, fps=float(tree.fps),
        n_frames=int(nodes.shape[0]), conifer=form == "conifer",
        mu_deg=float(tree.meta.get("mu_deg", 38.0)), fallbacks=fallbacks, leaves=leaf_info(tree),
        sway_excursion=sway_excursion(nodes, height), widths=branch_widths(parents, tree.radius, height),
        form=form, palm=palm_info(parents, nodes[0]) if form == "palm" else None,
        contours=source_contours(tree))


def source_contours(tree) -> list:
    """The crown contour of ``tree``'s envelope (:func:`.crown_space.envelope_contour`), or none
    when it has no envelope."""
    from ..envelope import envelope_from_meta
    poly = (tree.meta.get("envelope") or {}).get("polygon")
    env = envelope_from_polygon(np.asarray(poly, float)) if poly is not None else envelope_from_meta(tree.meta)
    if env is None or not len(env.z) or not np.max(env.radius) > 0:
        return []
    return [envelope_contour(env)]


def branch_widths(parents: np.ndarray, radius: np.ndarray, height: float) -> tuple[float, float]:
    """``(trunk, tip)``: the trunk base's radius and the median tip's radius as shares of the
    height (what generated trees' pipe-model radii are fitted to)."""
    r = np.asarray(radius, np.float64) / max(float(height), 1e-9)
    has_child = np.zeros(len(r), bool)
    has_child[np.asarray(parents)[np.asarray(parents) >= 0]] = True
    tip = float(np.median(r[~has_child])) if (~has_child).any() else float(r[0])
    return float(r[0]), float(min(tip, r[0]))


# ============================================================================ files

def dumps_species(model: SpeciesModel) -> str:
    """Indented JSON with every list of numbers on one line (readable and diffable)."""
    import re
    text = json.dumps(model.to_json(), indent=1, ensure_ascii=False)
    return re.sub(r"\[\s*([-0-9.eE,\s]*?)\s*\]", lambda m: "[" + re.sub(r"\s+", " ", m.group(1)) + "]", text)


def save_species(path: str | os.PathLike, model: SpeciesModel) -> None:
    """Write ``model`` as indented JSON to ``path`` atomically (temporary file + rename)."""
    from ..fileio import publish
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".json", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(dumps_species(model) + "\n")
        publish(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def load_species(path: str | os.PathLike) -> SpeciesModel:
    """Read a species file; :class:`InputError` for a missing, unreadable, foreign, newer or
    damaged file."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"species file '{path}' does not exist; pick a .json from the species library "
                         "or fit one from a reconstructed tree")
    from ..fileio import read_json
    data = read_json(path, f"species file '{path}'", "pick a .json written by Fit Species")
    model = SpeciesModel.from_json(data, f"species file '{path}'")
    if model.bark_dir is not None:                 # kept relative to the file: where it is now
        model.bark_dir = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)), model.bark_dir))
    return model


SPECIES_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "species")


@functools.lru_cache(maxsize=1)
def library_contours() -> tuple[np.ndarray, ...]:
    """The crown contours of the shipped species (:attr:`SpeciesModel.contours`), read once."""
    out: list[np.ndarray] = []
    for path in species_library().values():
        out += [np.asarray(c, np.float64) for c in load_species(path).contours]
    return tuple(out)


def species_library(folder: str | None = None) -> dict[str, str]:
    """``{name: path}`` of the species files shipped with the add-on (``species/*.json``), the
    name being the file name without ``.json``, sorted by name."""
    folder = folder or SPECIES_DIR
    if not os.path.isdir(folder):
        return {}
    names = sorted(f for f in os.listdir(folder) if f.lower().endswith(".json"))
    return {os.path.splitext(f)[0]: os.path.join(folder, f) for f in names}


def model_summary(model: SpeciesModel) -> dict:
    """Small dict for UIs and logs: mean angle/length ratios, dominant frequency per axis."""
    return {"angles_mean": (model.angles / model.angles.sum()).round(3).tolist(),
            "lengths_mean": (model.lengths / model.lengths.sum()).round(3).tolist(),
            "dominant_hz": [round(m.dominant_hz, 3) for m in model.motion],
            "peaks_hz": [m.peaks_hz().round(3).tolist() for m in model.motion],
            "conifer": model.conifer}
