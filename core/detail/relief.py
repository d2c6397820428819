"""Bark relief as geometry (issue 36 part 3, seed 001's geometric texture transfer): the bark's height
map moves the branch tubes' vertices along their ring's outward direction, so the furrows are in
the mesh (and in every export of it), not only in the shading.

The height map is the one the bark material shows: the photo's tile (:mod:`.bark_photo`, repeated
:func:`~.bark_photo.uv_repeats` times over the UV square) or the procedural bark's
(:func:`~.bark_texture.bark_textures`). It is sampled at each vertex's UV (``u = k/S + u0`` round the
tube, ``v`` its ring's), bilinear and periodic, from the map low-passed to what the vertices can
carry (:func:`mesh_band`: a Gaussian of :data:`BAND` vertex spacings, so the furrows are in the mesh and
the finer cells stay in the normal map instead of aliasing into noise), then centred and scaled to
a peak-to-peak depth:

    ``Δ = relief · (h − mean h) / (max h − min h) · r0 / r_max``  (``h`` the low-passed map)

metres along the ring's radial unit vector; ``r0`` the ring's radius before bark, ``r_max`` the
thickest ring's (twigs carry thinner bark, as the seed's scanned cuts do). The tube's mean radius
is kept. A joined fork's rings (:mod:`.forks`) keep their circles, the relief fading in over
:data:`FADE_RINGS` rings from them, so the junction's hull still meets them. A relief needs
vertices to show it: the tubes are built with at least :data:`RELIEF_SIDES` sides and
:data:`RELIEF_RINGS` rings a bone.
"""
from __future__ import annotations

import numpy as np

#: the fewest sides a tube with relief is built with (the procedural bark has 8 furrows round a tube: 4 vertices each)
RELIEF_SIDES = 32
#: the fewest rings a bone's tube with relief is built with
RELIEF_RINGS = 12
#: the low-pass Gaussian's σ in vertex spacings (its gain at the mesh's Nyquist frequency: e^(−π²/2) = 0.7 %)
BAND = 1.0
#: rings over which the relief fades in from a joined fork's ring
FADE_RINGS = 2


def sample_periodic(height: np.ndarray, uv: np.ndarray, repeats: int = 1) -> np.ndarray:
    """``(V,)`` bilinear samples of the periodic ``height (H, W)`` (row = ``v``, column = ``u``) at
    ``uv (V, 2)`` × ``repeats`` (the tile wraps in both directions)."""
    H, W = height.shape
    x = np.asarray(uv[:, 0], np.float64) * repeats * W - 0.5
    y = np.asarray(uv[:, 1], np.float64) * repeats * H - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    xi, yi = x0.astype(np.int64) % W, y0.astype(np.int64) % H
    xj, yj = (xi + 1) % W, (yi + 1) % H
    h = np.asarray(height, np.float64)
    return ((1 - fy) * ((1 - fx) * h[yi, xi] + fx * h[yi, xj]) + fy * ((1 - fx) * h[yj, xi] + fx * h[yj, xj]))


def mesh_band(height: np.ndarray, sigma_u: float, sigma_v: float) -> np.ndarray:
    """The periodic ``height (H, W)`` blurred by a Gaussian of ``sigma_u`` columns and
    ``sigma_v`` rows (in the frequency domain, so it wraps as the tile does)."""
    H, W = height.shape
    fy = np.fft.fftfreq(H)[:, None]
    fx = np.fft.fftfreq(W)[None, :]
    gain = np.exp(-2.0 * np.pi ** 2 * ((fy * sigma_v) ** 2 + (fx * sigma_u) ** 2))
    return np.fft.ifft2(np.fft.fft2(np.asarray(height, np.float64)) * gain).real


def relief_offsets(g: dict, height: np.ndarray, repeats: int, relief_m: float) -> np.ndarray:
    """The vertices' offsets ``(V, 3)`` metres for the tubes ``g`` of
    :func:`~.branch_mesh.tube_arrays` (module docstring)."""
    K, S = int(g["rings"]), int(g["sides"])
    B = len(g["r0"])
    H, W = height.shape
    dv = np.diff(np.asarray(g["v"], np.float64), axis=1)                 # ring spacing, tiles of v
    step_v = float(np.median(dv)) if dv.size else 1.0 / K
    height = mesh_band(height, BAND * W / (S * repeats), BAND * H * step_v * repeats)
    co = np.asarray(g["co"], np.float64).reshape(B, K, S, 3)
    radial = co - g["centre"][:, :, None]
    radial /= np.maximum(np.linalg.norm(radial, axis=-1, keepdims=True), 1e-12)
    u = np.arange(S)[None, None] / S + np.asarray(g["u0"], np.float64)[..., None]
    v = np.broadcast_to(g["v"][..., None], (B, K, S))
    h = sample_periodic(height, np.stack([u.ravel(), v.ravel()], axis=1), repeats)
    span = max(float(np.ptp(height)), 1e-9)
    centred = (h - float(np.mean(height))) / span
    r0 = np.asarray(g["r0"], np.float64)
    w = r0 / max(float(r0.max()), 1e-12)                                 # (B, K)
    plan = g.get("plan")
    if plan is not None:                         # 0 on a junction's ring, 1 from FADE_RINGS on
        ramp = np.minimum(np.arange(K), FADE_RINGS) / FADE_RINGS
        w = w * np.where(plan.head_cap[:, None], 1.0, ramp[None]) * np.where(plan.tail_cap[:, None], 1.0, ramp[::-1][None])
    scale = np.broadcast_to(w[..., None], (B, K, S)).ravel()
    return radial.reshape(-1, 3) * (relief_m * centred * scale)[:, None]
