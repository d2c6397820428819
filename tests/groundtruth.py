"""Scoring a 2D skeleton against a synthetic video's ground truth (``truth.npz``).

All distances are in pixels of frame 1 and normalized by the true tree height.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.spatial import cKDTree


@lru_cache(maxsize=None)
def true_labels(variant: str, seed: int | None = None, frames: int | None = None,
                width: int | None = None, height: int | None = None) -> np.ndarray:
    """``(H, W)`` label image of a sample variant's frame 1 (``synth_tree.LABEL_BRANCH`` /
    ``LABEL_LEAF``; rendered once per session), of its preset or of ``seed`` / ``frames`` /
    ``width`` / ``height``. Read only."""
    from tree_from_video.sample_videos import synth_tree
    cfg = synth_tree.config_for(variant, seed=seed, frames=frames, width=width, height=height)
    lab = synth_tree.render_labels(synth_tree.build_scene(cfg), 0)
    lab.setflags(write=False)
    return lab


def dist_to_polyline(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """``(P,)`` distance of every point of ``p (P, 2)`` to the polyline ``poly (K, 2)`` (px)."""
    a, b = poly[:-1], poly[1:]
    ab = b - a
    t = np.clip(((p[:, None] - a[None]) * ab[None]).sum(-1) / np.maximum((ab ** 2).sum(-1), 1e-9), 0, 1)
    return np.linalg.norm(p[:, None] - (a[None] + t[..., None] * ab[None]), axis=-1).min(1)


def sample_edges(nodes: np.ndarray, parents: np.ndarray, step: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``step`` px along every (parent, child) edge of ``nodes (N, 2)``; also their weights (px)."""
    c = np.flatnonzero(parents >= 0)
    a, b = nodes[parents[c]], nodes[c]
    length = np.linalg.norm(b - a, axis=1)
    n = np.maximum(1, np.ceil(length / step).astype(int))
    seg = np.repeat(np.arange(len(c)), n)
    offs = np.concatenate([(np.arange(k) + 0.5) / k for k in n])
    pts = a[seg] + (b - a)[seg] * offs[:, None]
    w = (length / n)[seg]
    return pts, w


def chamfer_coverage(skel_nodes, skel_parents, true_nodes, true_parents, height, cover_tol=0.03):
    """(symmetric chamfer / height, share of true branch length within ``cover_tol``·height)."""
    sp_, _ = sample_edges(skel_nodes, skel_parents)
    tp, tw = sample_edges(true_nodes, true_parents)
    if len(sp_) == 0:
        return 1.0, 0.0
    d_ts = cKDTree(sp_).query(tp)[0]
    d_st = cKDTree(tp).query(sp_)[0]
    chamfer = 0.5 * (np.average(d_ts, weights=tw) + d_st.mean()) / height
    coverage = float(np.sum(tw[d_ts <= cover_tol * height]) / tw.sum())
    return float(chamfer), coverage


def irregular(times) -> bool:
    """True when frame ``times (F,)`` s are not evenly spaced (a variable-frame-rate clip)."""
    if times is None or len(times) < 3:
        return False
    d = np.diff(np.asarray(times, float))
    return bool(np.ptp(d) > 1e-6 * max(abs(float(d.mean())), 1e-12))


def dominant_frequency(x: np.ndarray, fps: float, times: np.ndarray | None = None) -> float:
    """Frequency (Hz) of the largest FFT peak of ``x (F,)`` (mean removed, Hann window, parabolic refinement).
    With irregular frame ``times (F,)`` s, ``x`` is first resampled linearly onto F even steps at the mean rate
    (``fps`` is then not used)."""
    if irregular(times):
        t = np.asarray(times, float)[:len(x)]
        grid = np.linspace(t[0], t[-1], len(t))
        x = np.interp(grid, t, np.asarray(x, float))
        fps = (len(t) - 1) / (t[-1] - t[0])
    x = np.asarray(x, float) - np.mean(x)
    n = len(x)
    pad = 8 * n
    spec = np.abs(np.fft.rfft(x * np.hanning(n), pad))
    spec[0] = 0
    k = int(np.argmax(spec))
    if 0 < k < len(spec) - 1:
        a, b, c = spec[k - 1:k + 2]
        denom = a - 2 * b + c
        if denom < 0:
            k = k + 0.5 * (a - c) / denom
    return float(k * fps / pad)


@dataclass
class Score:
    chamfer1: float       # frame-1 chamfer / height
    chamfer_all: float    # mean over frames
    coverage: float       # frame-1 coverage
    tip_corr: float       # median Pearson of x displacement of matched tips
    freq_err: float       # median |Δf| Hz of matched tips' dominant sway frequency
    n_nodes: int


def score(skel_parents, skel_nodes2d, truth, frame_step: int = 4) -> Score:
    """Compare a skeleton (``parents (N,)``, ``nodes2d (F, N, 2)``) to a truth npz dict."""
    tn = truth["nodes2d"]
    tpar = truth["parents"]
    h = float(truth["height_px"])
    fps = float(truth["fps"])
    F = min(len(tn), len(skel_nodes2d))
    times = truth["times"][:F] if "times" in truth and irregular(truth["times"]) else None
    c1, cov = chamfer_coverage(skel_nodes2d[0], skel_parents, tn[0], tpar, h)
    call = np.mean([chamfer_coverage(skel_nodes2d[t], skel_parents, tn[t], tpar, h)[0]
                    for t in range(0, F, frame_step)])
    has_child = np.zeros(len(skel_parents), bool)
    has_child[skel_parents[skel_parents >= 0]] = True
    tips = np.flatnonzero(~has_child)
    _, match = cKDTree(tn[0]).query(skel_nodes2d[0, tips])
    corrs, ferrs = [], []
    for s, t in zip(tips, match):
        xs = skel_nodes2d[:F, s, 0] - skel_nodes2d[0, s, 0]
        xt = tn[:F, t, 0] - tn[0, t, 0]
        if np.std(xs) < 1e-9 or np.std(xt) < 1e-9:
            corrs.append(0.0)
            continue
        corrs.append(float(np.corrcoef(xs, xt)[0, 1]))
        ferrs.append(abs(dominant_frequency(xs, fps, times) - dominant_frequency(xt, fps, times)))
    return Score(c1, float(call), cov, float(np.median(corrs)) if corrs else 0.0,
                 float(np.median(ferrs)) if ferrs else 99.0, len(skel_parents))


def sample_edges_3d(nodes: np.ndarray, parents: np.ndarray, step: float = 1.0) -> np.ndarray:
    """Points every ``step`` units along every edge of ``nodes (N, 3)``."""
    pts, _ = sample_edges(nodes, parents, step)
    return pts


def chamfer_3d(a: np.ndarray, b: np.ndarray, height: float) -> float:
    """Symmetric mean nearest-point distance between point sets ``a`` and ``b`` / height."""
    return float(0.5 * (cKDTree(b).query(a)[0].mean() + cKDTree(a).query(b)[0].mean()) / height)


def lift_in_truth_frame(nodes_plane: np.ndarray, base_px: np.ndarray, truth: dict) -> np.ndarray:
    """Our plane coordinates (px from our trunk base) → the truth's frame (x from cx, z from ground)."""
    out = np.array(nodes_plane, float)
    out[..., 0] += base_px[0] - float(truth["cx"])
    out[..., 2] += float(truth["ground_v"]) - base_px[1]
    return out


def depth_oracles(nodes_plane: np.ndarray, parents: np.ndarray, base_px: np.ndarray, truth: dict) -> dict:
    """What a lift's depths ``nodes_plane[:, 1]`` (px, plane frame) lose to their signs and to their
    magnitudes: each node matched to the true node nearest it on (x, z) in frame 1, its true depth
    from the true base (the global sign that agrees better with ours), and the 3D chamfer over the
    flat truth's (:func:`lift_scores`) with the true magnitudes on our signs (``true_magnitude``),
    our magnitudes on the true signs (``true_sign``) and the true depths (``true_depth``: what the
    2D trace alone allows); ``sign_agreement`` over the nodes farther than 2 % of the height from
    the trunk's plane."""
    from scipy.spatial import cKDTree
    h = float(truth["height_px"])
    tn = truth["nodes3d"][0].astype(np.float64)
    ours = lift_in_truth_frame(nodes_plane, base_px, truth)
    _, j = cKDTree(tn[:, [0, 2]]).query(ours[:, [0, 2]])
    oy = np.asarray(nodes_plane, np.float64)[:, 1]
    ty = tn[j, 1] - tn[0, 1]
    if np.abs(oy + ty).sum() < np.abs(oy - ty).sum():
        ty = -ty
    far = np.abs(ty) > 0.02 * h

    def ratio(y: np.ndarray) -> float:
        x = np.array(nodes_plane, np.float64)
        x[:, 1] = y
        r = lift_scores(x, parents, base_px, truth)
        return r["chamfer"] / r["flat_truth"]
    return {"sign_agreement": float((np.sign(oy) == np.sign(ty))[far].mean()) if far.any() else float("nan"),
            "true_magnitude": ratio(np.abs(ty) * np.where(oy >= 0, 1.0, -1.0)),
            "true_sign": ratio(np.abs(oy) * np.where(ty >= 0, 1.0, -1.0)),
            "true_depth": ratio(ty)}


def lift_scores(nodes_plane: np.ndarray, parents: np.ndarray, base_px: np.ndarray, truth: dict) -> dict:
    """3D chamfer of a lifted frame-1 skeleton vs the true tree (best of both depth signs), the true
    tree flattened to depth 0 as the baseline, and depth/width extents."""
    h = float(truth["height_px"])
    tn = truth["nodes3d"][0]
    ts = sample_edges_3d(tn, truth["parents"])
    ours = lift_in_truth_frame(nodes_plane, base_px, truth)
    os_ = sample_edges_3d(ours, parents)
    mirrored = os_ * np.array([1.0, -1.0, 1.0])
    flat = ts * np.array([1.0, 0.0, 1.0])
    return {
        "chamfer": min(chamfer_3d(os_, ts, h), chamfer_3d(mirrored, ts, h)),
        "flat_truth": chamfer_3d(flat, ts, h),
        "depth_ratio": float(np.ptp(ours[:, 1]) / max(np.ptp(ours[:, 0]), 1e-9)),
        "true_depth_ratio": float(np.ptp(tn[:, 1]) / max(np.ptp(tn[:, 0]), 1e-9)),
    }
