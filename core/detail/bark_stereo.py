"""Bark height from several photos of the same bark (issue 36, seed 004's photogrammetry in two
views): where two hand-held close-ups overlap, the relief is in their parallax, not in their shading
(a dark blotch is not a crevice, a grazing light makes slopes bright, not plates). Pure numpy and
OpenCV; :func:`.bark_photo.bark_maps` uses it for every photo that has a partner.

Plane plus parallax (Irani & Anandan 1996; Sawhney 1994):

1. **The bark's plane**: SIFT features of both photos, matched by Lowe's ratio test (0.75), and the
   homography ``H`` of the most matches (RANSAC, 3 px) maps the other photo onto this one. Photos
   with fewer than :data:`MIN_INLIERS` inliers do not overlap (``None``).
2. **Residual motion**: dense optical flow (OpenCV's DIS) from this photo to the other warped by
   ``H``, minus its own blur at σ = :data:`FLOW_SIGMA` of the shorter side (what the homography
   leaves of a trunk's curvature and the lens's distortion). What remains is the parallax of the
   relief: for a point at height ``γ`` (relative to its depth) above the plane it is
   ``μ(x) = γ(x) · T_z / d · (x − e)`` (Irani & Anandan, eq. 5), along the line from the epipole
   ``e``, proportional to the distance from it.
3. **Which way is out**: ``H`` decomposed (Malis & Vargas 2007, OpenCV's ``decomposeHomographyMat``)
   with an assumed pinhole ``K`` (focal length :data:`FOCAL` × the longer side, the centre the
   principal point) into ``(R, t, n)``, ``X_A = R X_B + t``: ``t`` is the other camera's centre in
   this one's frame, the solutions whose plane lies in front of the other camera (``nᵀ K⁻¹ p > 0`` for
   nine in ten of its matched points ``p``), of those the one whose parallax direction
   ``δ(x) = (K t)_xy − x (K t)_z`` the residuals follow best (least ``Σ |r × δ̂| |r|``). A point
   raised off the plane toward the cameras is seen displaced along ``+δ`` in this photo against where
   the plane puts it (``X_A − H X_B = t (1 + nᵀX_B / d)``, positive for it), so its residual flow
   points along ``−δ``. (The sign is what the decomposition gives; a wrong ``K`` bends ``δ``, not
   its sign.)
4. **Height**: ``γ = −r · δ / |δ|²`` (``|δ|`` grows with the distance from the epipole, as the
   parallax does), high-passed like the shading height (minus its blur at ``sigma``) and scaled to
   [0, 1] between its 1st and 99th percentiles. Pixels the warped photo does not cover, or whose
   flow does not come back (forward–backward difference > :data:`CHECK_PX`), are not valid; the
   caller keeps the shading height there.
"""
from __future__ import annotations

import cv2
import numpy as np

#: the fewest homography inliers of two photos that overlap
MIN_INLIERS = 40
#: σ of the flow's low-pass (share of the shorter side): what the homography leaves, not the relief
FLOW_SIGMA = 0.06
#: the largest forward–backward flow difference (px) of a valid pixel
CHECK_PX = 1.0
#: the assumed focal length, × the photo's longer side (a phone's main camera: 65–75° across)
FOCAL = 0.8


def _grey(img: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img


def features(img: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """``(points (M, 2) px, descriptors (M, 128) or None)``: SIFT of ``img`` (BGR or grey uint8)."""
    kps, desc = cv2.SIFT_create(nfeatures=4000).detectAndCompute(_grey(img), None)
    return np.array([k.pt for k in kps], np.float32).reshape(-1, 2), desc


def plane_homography(fa: tuple, fb: tuple) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """``(H (3, 3) mapping the other photo's pixels onto this one's, inlier points in this one (M, 2),
    the same in the other)`` of their :func:`features` ``fa``, ``fb``; ``H`` None when they do not
    overlap (fewer than :data:`MIN_INLIERS` inliers): module docstring, 1."""
    (ka, da), (kb, db) = fa, fb
    none = np.zeros((0, 2), np.float32)
    if da is None or db is None or len(ka) < MIN_INLIERS or len(kb) < MIN_INLIERS:
        return None, none, none
    pairs = cv2.BFMatcher(cv2.NORM_L2).knnMatch(da, db, k=2)
    good = [m[0] for m in pairs if len(m) == 2 and m[0].distance < 0.75 * m[1].distance]
    if len(good) < MIN_INLIERS:
        return None, none, none
    pa = ka[[m.queryIdx for m in good]]
    pb = kb[[m.trainIdx for m in good]]
    H, inl = cv2.findHomography(pb, pa, cv2.RANSAC, 3.0)
    if H is None or inl is None or int(inl.sum()) < MIN_INLIERS:
        return None, none, none
    ok = inl.ravel() > 0
    return H, pa[ok], pb[ok]


def parallax_direction(H: np.ndarray, shape: tuple[int, int], pa: np.ndarray, pb: np.ndarray,
                       r: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """``δ (h, w, 2)``: the direction a point raised off the plane is displaced in this photo
    (module docstring, 3.); ``H`` other → this, ``pa``, ``pb`` ``(M, 2)`` its inlier matches,
    ``r (h, w, 2)`` the residual flow, ``weight (h, w)`` where to compare with it."""
    h, w = shape
    fk = FOCAL * max(h, w)
    K = np.array([[fk, 0.0, w / 2.0], [0.0, fk, h / 2.0], [0.0, 0.0, 1.0]])
    _, Rs, ts, ns = cv2.decomposeHomographyMat(H, K)
    # the plane in front of the other camera: nᵀ K⁻¹ p > 0 (n points from the camera to the plane) for
    # its matched points (OpenCV's filterHomographyDecompByVisibleRefpoints kept the mirrored solution
    # on a sideways move to the left)
    rays = np.linalg.solve(K, np.vstack([pb.T.astype(np.float64), np.ones(len(pb))]))
    idx = [i for i in range(len(ts)) if np.mean(np.asarray(ns[i]).ravel() @ rays > 0) > 0.9] or list(range(len(ts)))
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    rw, mag = r[weight], np.hypot(r[weight][:, 0], r[weight][:, 1])
    best, best_cost = None, np.inf
    for i in idx:
        e = K @ np.asarray(ts[i], np.float64).ravel()
        d = np.dstack([e[0] - x * e[2], e[1] - y * e[2]])
        dw = d[weight] / np.maximum(np.hypot(d[weight][:, 0], d[weight][:, 1]), 1e-12)[:, None]
        cost = float(np.sum(np.abs(rw[:, 0] * dw[:, 1] - rw[:, 1] * dw[:, 0]) * mag))
        if cost < best_cost:
            best, best_cost = d, cost
    assert best is not None
    return best


def stereo_height(img: np.ndarray, other: np.ndarray, sigma: float, fa: tuple | None = None,
                  fb: tuple | None = None) -> tuple[np.ndarray, np.ndarray, int] | None:
    """``(height (H, W) in [0, 1], valid (H, W) bool, inliers)`` of ``img`` from its parallax against
    ``other`` (both BGR uint8, :mod:`.bark_photo`'s scale; ``fa``, ``fb`` their :func:`features` if
    known); ``sigma`` the high-pass's σ (px). None when they do not overlap."""
    H, pa, pb = plane_homography(fa or features(img), fb or features(other))
    if H is None:
        return None
    Hh, W = img.shape[:2]
    ga = _grey(img)
    warped = cv2.warpPerspective(_grey(other), H, (W, Hh), flags=cv2.INTER_LINEAR)
    cover = cv2.warpPerspective(np.full(other.shape[:2], 255, np.uint8), H, (W, Hh), flags=cv2.INTER_NEAREST)
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    fwd = dis.calc(ga, warped, None).astype(np.float64)
    bwd = dis.calc(warped, ga, None).astype(np.float64)
    y, x = np.mgrid[0:Hh, 0:W].astype(np.float32)
    back = np.dstack([cv2.remap(bwd[..., k].astype(np.float32), x + fwd[..., 0].astype(np.float32),
                                y + fwd[..., 1].astype(np.float32), cv2.INTER_LINEAR) for k in range(2)])
    inside = cv2.erode(cover, np.ones((15, 15), np.uint8)) > 0
    valid = inside & (np.hypot(*(fwd + back).transpose(2, 0, 1)) <= CHECK_PX)
    if valid.mean() < 0.2:
        return None
    # 2. the residual: the flow minus its low-pass (the homography's leftovers), normalised convolution
    s_flow = FLOW_SIGMA * min(Hh, W)
    wv = valid.astype(np.float64)
    low = np.dstack([cv2.GaussianBlur(fwd[..., k] * wv, (0, 0), s_flow) for k in range(2)])
    low /= np.maximum(cv2.GaussianBlur(wv, (0, 0), s_flow), 1e-6)[..., None]
    r = fwd - low
    # 3. which way is out, 4. the parallax along it
    mag = np.hypot(r[..., 0], r[..., 1])
    strong = valid & (mag > np.median(mag[valid]))
    d = parallax_direction(H, (Hh, W), pa, pb, r, strong)
    gamma = -np.sum(r * d, axis=-1) / np.maximum(np.sum(d * d, axis=-1), 1e-12) * float(np.hypot(W, Hh))
    gamma = np.where(valid, gamma, 0.0)
    fill = np.where(valid, gamma, float(np.median(gamma[valid])))
    hp = fill - cv2.GaussianBlur(fill, (0, 0), sigma)
    lo, hi = np.percentile(hp[valid], [1, 99])
    return np.clip((hp - lo) / max(hi - lo, 1e-9), 0.0, 1.0).astype(np.float32), valid, len(pa)
