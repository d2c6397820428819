"""Scoring 3D motion against the synthetic ground truth; tip motion in 2D and 3D; the dense-flow
reference that real footage (no ground truth) is measured with (:func:`flow_reference_correlation`)."""
from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import cKDTree


def joints(parents: np.ndarray) -> np.ndarray:
    """``(E,)`` the nodes whose edge has a parent edge (a parent that is not the root): the joints
    :func:`angle_changes` reports, in its column order."""
    return np.flatnonzero((parents >= 0) & (parents[np.maximum(parents, 0)] >= 0))


def angle_changes(nodes: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """``(F, E)`` |α(t) − α(1)| radians for every edge that has a parent edge (α = angle between
    the edge and its parent edge, the :func:`joints`), nodes ``(F, N, 3)``."""
    c = joints(parents)
    p = parents[c]
    g = parents[p]
    a = nodes[:, c] - nodes[:, p]
    b = nodes[:, p] - nodes[:, g]
    cos = np.sum(a * b, -1) / np.maximum(np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1), 1e-12)
    ang = np.arccos(np.clip(cos, -1, 1))
    return np.abs(ang - ang[:1])


def true_bending(truth: dict, frames: int) -> dict:
    """The truth's 95th percentile of the change of branch angles (degrees, :func:`angle_changes`
    over its first ``frames``): ``all`` joints, and ``rigid`` without the joints of the thinnest
    branches that swing on their own (the wind variants' ``thin_swing_deg``: 5–15° at 0.8–2 Hz about
    their joint, ``truth["swing_deg"]`` per branch). On the gusty clips those joints carry the
    truth's bending (gusts dev seeds: all 11.6–12.3°, rigid 2.6–2.9°); a reconstruction is compared
    with ``rigid`` where the 2D skeleton does not resolve such twigs."""
    nodes, parents = truth["nodes3d"][:frames].astype(np.float64), truth["parents"]
    da = np.degrees(angle_changes(nodes, parents))
    c = joints(parents)
    swing = truth.get("swing_deg")
    swinging = np.zeros(len(c), bool) if swing is None else np.asarray(swing)[truth["branch_id"][c]] > 0
    rigid = da[:, ~swinging]
    return {"all": float(np.percentile(da, 95)),
            "rigid": float(np.percentile(rigid, 95)) if rigid.size else float("nan")}


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


# --- 2D and 3D tip motion against the truth, and the real-footage reference (issue 18) -----------

def _pearson(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two series; 0 when either is constant."""
    if a.std() < 1e-9 or b.std() < 1e-9:
        return 0.0
    return float(np.corrcoef(a, b)[0, 1])


def _median(v: list) -> float:
    return float(np.median(v)) if v else float("nan")


def _tip_stats(ours_x: np.ndarray, true_x: np.ndarray, truth: dict) -> dict:
    """Medians over matched tips of x-displacement correlation, std ratio and dominant-frequency
    error; ``ours_x``, ``true_x`` (F, T) px."""
    from groundtruth import dominant_frequency, irregular
    F = ours_x.shape[0]
    times = truth["times"][:F] if "times" in truth and irregular(truth["times"]) else None
    fps = float(truth["fps"])
    corr, amp, ferr = [], [], []
    for xs, xt in zip((ours_x - ours_x[:1]).T, (true_x - true_x[:1]).T):
        corr.append(_pearson(xs, xt))
        amp.append(xs.std() / max(xt.std(), 1e-9))
        if xs.std() > 1e-9 and xt.std() > 1e-9:
            ferr.append(abs(dominant_frequency(xs, fps, times) - dominant_frequency(xt, fps, times)))
    return {"corr": _median(corr), "amp": _median(amp), "freq_err": _median(ferr), "n": ours_x.shape[1]}


def tip_motion(parents: np.ndarray, nodes2d: np.ndarray, truth: dict) -> dict:
    """A 2D skeleton's tips (``parents (N,)``, ``nodes2d (F, N, 2)`` frame-1 px) against the truth:
    each tip matched to the nearest true node in frame 1 (as :func:`groundtruth.score`); the medians
    over tips of the Pearson correlation of x displacement (``corr``), of the std ratio ours / true
    (``amp``) and of the dominant-frequency error in Hz (``freq_err``, from the truth's frame times),
    and ``n`` tips."""
    tn = truth["nodes2d"]
    F = min(len(tn), len(nodes2d))
    tp = tips(parents)
    _, match = cKDTree(tn[0]).query(nodes2d[0, tp])
    return _tip_stats(np.asarray(nodes2d[:F, tp, 0], float), np.asarray(tn[:F, match, 0], float), truth)


def tip_motion_3d(nodes_plane: np.ndarray, parents: np.ndarray, base_px: np.ndarray, truth: dict) -> dict:
    """Like :func:`tip_motion` for a solved 3D motion ``nodes_plane (F, N, 3)`` px (plane frame: x right,
    z up from our trunk base ``base_px`` (2,)): tips matched to the nearest true node on (x, z) in frame
    1, x displacement against the true ``nodes3d``."""
    from groundtruth import lift_in_truth_frame
    tn = truth["nodes3d"].astype(np.float64)
    F = min(len(tn), len(nodes_plane))
    ours = lift_in_truth_frame(nodes_plane[:F], base_px, truth)
    tp = tips(parents)
    _, match = cKDTree(tn[0][:, [0, 2]]).query(ours[0, tp][:, [0, 2]])
    return _tip_stats(ours[:, tp, 0], tn[:F, match, 0], truth)


#: Farneback settings of the real-footage reference (pyramid 0.5 x 4 levels, window 21; iterations,
#: poly_n and poly_sigma are OpenCV's usual 3, 5, 1.1)
FARNEBACK = dict(pyr_scale=0.5, levels=4, winsize=21, iterations=3, poly_n=5, poly_sigma=1.1, flags=0)


def flow_reference(video, outline_mask: np.ndarray, points: np.ndarray, frames: int | None = None,
                   step: int = 3, ring_px: int = 31, sigma_px: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """The real-footage motion reference at ``points (P, 2)`` frame-1 px: dense Farneback flow
    (:data:`FARNEBACK`) from frame 1 to every ``step``-th frame, minus the median flow outside the
    outline dilated by ``ring_px``, blurred with ``sigma_px``, sampled bilinearly at the points.

    ``video`` a path (frames decoded in order) or a sequence of BGR/grey frames; ``outline_mask``
    (H, W) non-zero inside the outline; frames are resized to the mask's size when they differ.
    ``frames`` limits the decoded frames to the first ``frames``. Returns (frame indices (K,) from 0,
    displacement (K, P, 2) px, 0 at frame 0)."""
    h, w = outline_mask.shape[:2]
    k = 2 * int(ring_px) + 1
    near = cv2.dilate((outline_mask > 0).astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    bg = near == 0
    pts = np.asarray(points, np.float32).reshape(1, -1, 2)
    mapx, mapy = pts[..., 0].copy(), pts[..., 1].copy()

    def gray(img):
        g = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        return g if g.shape == (h, w) else cv2.resize(g, (w, h), interpolation=cv2.INTER_AREA)

    def frames_of():
        if isinstance(video, (str, bytes)) or hasattr(video, "__fspath__"):
            cap = cv2.VideoCapture(str(video))
            try:
                while True:
                    ok, img = cap.read()
                    if not ok:
                        return
                    yield img
            finally:
                cap.release()
        else:
            yield from video

    idx, disp, g0 = [], [], None
    for i, img in enumerate(frames_of()):
        if frames is not None and i >= frames:
            break
        if i % step:
            continue
        g = gray(img)
        if g0 is None:
            g0 = g
            idx.append(0)
            disp.append(np.zeros((pts.shape[1], 2), np.float32))
            continue
        flow = cv2.calcOpticalFlowFarneback(g0, g, None, **FARNEBACK)
        if bg.any():
            flow = flow - np.median(flow[bg], axis=0)
        flow = cv2.GaussianBlur(flow.astype(np.float32), (0, 0), sigma_px)
        fx = cv2.remap(flow[..., 0], mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        fy = cv2.remap(flow[..., 1], mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        idx.append(i)
        disp.append(np.stack([fx[0], fy[0]], -1))
    return np.array(idx, int), np.array(disp, np.float32).reshape(len(idx), pts.shape[1], 2)


def flow_reference_correlation(video, outline_mask: np.ndarray, nodes2d: np.ndarray, frames: int | None = None,
                               top: int = 30, min_std: float = 0.2, step: int = 3,
                               reference: tuple[np.ndarray, np.ndarray] | None = None,
                               exclude: np.ndarray | None = None) -> dict:
    """The issue's real-footage metric for a moving 2D skeleton ``nodes2d (F, N, 2)`` (frame-1 px, one
    row per decoded frame from the clip's first): the reference (:func:`flow_reference`, sampled at each
    node's frame-1 position); over the ``top`` nodes whose reference x displacement has the largest std
    (at least ``min_std`` px), the median Pearson correlation of x displacement, node vs reference
    (``corr``), the median std ratio node / reference (``amp``), ``n`` nodes used (``corr`` NaN when
    none moves enough), ``ref`` the (frame indices, displacement) reference (pass it back as
    ``reference`` to score other nodes with the same frame-1 positions without a second flow pass).
    ``exclude (F, H, W)`` bool (e.g. a synthetic clip's ``foreground_mask``): nodes whose frame-1
    position is excluded in any sampled frame are left out (the metric itself has no such mask)."""
    nodes2d = np.asarray(nodes2d, np.float64)
    n_rows = nodes2d.shape[0] if frames is None else min(frames, nodes2d.shape[0])
    if reference is None:
        reference = flow_reference(video, outline_mask, nodes2d[0], n_rows, step)
    idx, disp = reference
    keep = idx < n_rows
    idx, rx = idx[keep], disp[keep][..., 0].astype(np.float64)
    nx = nodes2d[idx, :, 0] - nodes2d[0, :, 0]
    sd = rx.std(axis=0) if len(idx) > 1 else np.zeros(nodes2d.shape[1])
    ok = sd >= min_std
    if exclude is not None:
        h, w = exclude.shape[1:]
        u = np.clip(np.rint(nodes2d[0, :, 0]).astype(int), 0, w - 1)
        v = np.clip(np.rint(nodes2d[0, :, 1]).astype(int), 0, h - 1)
        ok &= ~exclude[idx][:, v, u].any(axis=0)
    cand = np.flatnonzero(ok)
    sel = cand[np.argsort(-sd[cand])][:top]
    if len(sel) == 0:
        return {"corr": float("nan"), "amp": float("nan"), "n": 0, "nodes": sel, "ref": (idx, disp[keep])}
    corr = [_pearson(nx[:, i], rx[:, i]) for i in sel]
    amp = [nx[:, i].std() / rx[:, i].std() for i in sel]
    return {"corr": float(np.median(corr)), "amp": float(np.median(amp)), "n": int(len(sel)), "nodes": sel,
            "ref": (idx, disp[keep])}
