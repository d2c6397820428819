"""Scoring 3D motion against the synthetic ground truth."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def angle_changes(nodes: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """``(F, E)`` |α(t) − α(1)| radians for every edge that has a parent edge (α = angle between
    the edge and its parent edge), nodes ``(F, N, 3)``."""
    c = np.flatnonzero((parents >= 0) & (parents[np.maximum(parents, 0)] >= 0))
    p = parents[c]
    g = parents[p]
    a = nodes[:, c] - nodes[:, p]
    b = nodes[:, p] - nodes[:, g]
    cos = np.sum(a * b, -1) / np.maximum(np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1), 1e-12)
    ang = np.arccos(np.clip(cos, -1, 1))
    return np.abs(ang - ang[:1])


def tips(parents: np.ndarray) -> np.ndarray:
    has_child = np.zeros(len(parents), bool)
    has_child[parents[parents >= 0]] = True
    return np.flatnonzero(~has_child)


def motion_scores(nodes_plane: np.ndarray, parents: np.ndarray, targets_plane: np.ndarray,
                  base_px: np.ndarray, truth: dict) -> dict:
    """Reprojection, length, angle-change and tip statistics of a solved motion ``(F, N, 3)``."""
    h = float(truth["height_px"])
    F = nodes_plane.shape[0]
    reproj = np.linalg.norm(nodes_plane[..., [0, 2]] - targets_plane, axis=-1)[1:] / h
    c = np.flatnonzero(parents >= 0)
    L = np.linalg.norm(nodes_plane[:, c] - nodes_plane[:, parents[c]], axis=-1)
    length_change = np.abs(L / L[:1] - 1).max()
    ours_da = angle_changes(nodes_plane, parents)
    tn = truth["nodes3d"][:F].astype(np.float64)
    true_da = angle_changes(tn, truth["parents"])
    # tips matched to the nearest true node in frame 1 (2D), in the truth's frame
    ours = nodes_plane.copy()
    ours[..., 0] += base_px[0] - float(truth["cx"])
    ours[..., 2] += float(truth["ground_v"]) - base_px[1]
    tp = tips(parents)
    _, m = cKDTree(tn[0][:, [0, 2]]).query(ours[0, tp][:, [0, 2]])
    def amplitude(x):                     # (F, T, C) → (T,) RMS distance from the mean position
        return np.sqrt(((x - x.mean(0)) ** 2).sum(-1).mean(0))
    amp_o = amplitude(ours[:, tp])
    amp_t = amplitude(tn[:, m])
    amp_o2 = amplitude(ours[:, tp][..., [0, 2]])
    amp_t2 = amplitude(tn[:, m][..., [0, 2]])
    amp_2d = amplitude(targets_plane[:, tp])
    def tip_corr(x):                      # x: (F, N) tip x positions, matched as above
        out = []
        for i, j in zip(tp, m):
            a = x[:, i] - x[0, i]
            b = tn[:, j, 0] - tn[0, j, 0]
            out.append(np.corrcoef(a, b)[0, 1] if a.std() > 1e-9 and b.std() > 1e-9 else 0.0)
        return float(np.median(out))
    return {
        "reproj_median": float(np.median(reproj)), "reproj_max": float(reproj.max()),
        "length_change": float(length_change),
        "angle95": float(np.degrees(np.percentile(ours_da, 95))), "angle_max": float(np.degrees(ours_da.max())),
        "true_angle95": float(np.degrees(np.percentile(true_da, 95))), "true_angle_max": float(np.degrees(true_da.max())),
        "tip_amplitude_ratio": float(np.median(amp_o / np.maximum(amp_t, 1e-9))),
        "tip_amplitude_ratio_xz": float(np.median(amp_o2 / np.maximum(amp_t2, 1e-9))),
        "tip_amplitude_ratio_2d": float(np.median(amp_2d / np.maximum(amp_t2, 1e-9))),
        "tip_corr": tip_corr(ours[..., 0]),
        "tip_corr_2d": tip_corr(targets_plane[..., 0]),
    }
