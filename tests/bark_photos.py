"""Synthetic close-ups of bark for the bark-from-photo tests (issue 36): vertical furrows whose
course wanders, plates with fine cells, moss in some crevices, pale lichen spots, a light gradient
across the photo as a hand-held shot has, sensor noise and JPEG. Returns the photo and the true
moss and lichen masks."""
import cv2
import numpy as np


def smooth_noise(shape, sigma, rng):
    n = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), sigma)
    return (n - n.mean()) / (n.std() + 1e-9)


def bark_photo(seed: int, size=(360, 480), moss_share=0.12, lichen_share=0.03, light=0.7, quality=85):
    """``(photo BGR uint8 (H, W, 3), moss (H, W) bool, lichen (H, W) bool)``; ``light`` the light's
    fall-off across the photo (1: none)."""
    rng = np.random.default_rng(seed)
    H, W = size
    y, x = np.mgrid[0:H, 0:W].astype(np.float32)
    wander = 14.0 * smooth_noise((H, W), 40, rng)
    furrow = 0.5 + 0.5 * np.cos(2 * np.pi * (x + wander) / rng.uniform(38, 52))
    cells = smooth_noise((H, W), 1.5, rng)
    height = np.clip(0.75 * furrow ** 0.6 + 0.12 * cells, 0, 1)
    base = np.array([38, 62, 92], np.float32) * rng.uniform(0.85, 1.15, 3)          # BGR brown
    img = base[None, None] * (0.35 + 1.0 * height[..., None])
    blob = smooth_noise((H, W), 10, rng) - 1.2 * height
    moss = blob > np.quantile(blob, 1 - moss_share)
    moss_col = np.array([40, 120, 80], np.float32) * (0.7 + 0.5 * height[..., None])
    img = np.where(moss[..., None], moss_col, img)
    spots = smooth_noise((H, W), 3, rng) + 0.8 * height
    lichen = (spots > np.quantile(spots, 1 - lichen_share)) & ~moss
    img = np.where(lichen[..., None], np.array([178, 190, 186], np.float32) * (0.9 + 0.1 * height[..., None]), img)
    fall = light + (1 - light) * (x / W * 0.6 + y / H * 0.4)[..., None] / 1.0
    img = img * (fall / fall.mean())
    img += rng.normal(0, 3.0, img.shape)
    img = np.clip(img, 0, 255).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    return cv2.imdecode(buf, cv2.IMREAD_COLOR), moss, lichen


def look_at(eye, target):
    """``(R, eye)``: a pinhole camera at ``eye`` (cm) looking at ``target``; ``R`` rows the camera's
    x (right), y (down) and z (forward) axes in world coordinates (world z up, out of the bark)."""
    eye, target = np.asarray(eye, np.float64), np.asarray(target, np.float64)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z]), eye


def bark_pair(seed: int, size=(480, 640), move=(4.0, 1.2, -0.5), distance_cm=30.0, relief_cm=1.5,
              light=(-0.7, 0.25, 0.65), quality=90):
    """``(photo A, photo B, true height seen by A (H, W) cm, the same seen by B)``: one patch of bark
    (30 × 22 cm, furrows, plates and cells ``relief_cm`` deep) photographed twice by hand from
    ``distance_cm``, the second camera moved by ``move`` (cm: right, up the trunk, toward it) and
    turned back onto the patch (which runs past both frames); rendered by splatting the surface
    (0.02 cm samples) into each camera with a depth test. Harder than :func:`bark_photo` for a height
    from shading: the bark's colour has its own blotches and stains, independent of the relief, and
    the light grazes from one side (``light``), so dark is not deep."""
    rng = np.random.default_rng(seed)
    H, W = size
    step = 0.02
    gy, gx = np.mgrid[0:1100, 0:1500].astype(np.float32)
    X, Y = gx * step, gy * step                                              # cm, 30 × 22
    wander = 0.6 * smooth_noise(X.shape, 60, rng)
    period = rng.uniform(1.6, 2.2)
    furrow = 0.5 + 0.5 * np.cos(2 * np.pi * (X + wander) / period)
    plates = smooth_noise(X.shape, 25, rng)
    cells = smooth_noise(X.shape, 4, rng)
    h = np.clip(0.65 * furrow ** 0.7 + 0.15 * plates + 0.08 * cells, 0, None)
    h = relief_cm * (h - h.min()) / (h.max() - h.min())
    # colour: brown with blotches and stains of its own (not the relief), lit by a grazing light
    blotch = smooth_noise(X.shape, 40, rng)
    stain = smooth_noise(X.shape, 12, rng) > 1.0
    base = np.array([40, 66, 96], np.float32) * rng.uniform(0.85, 1.15, 3)
    albedo = base[None, None] * (0.75 + 0.25 * np.tanh(blotch))[..., None]
    albedo = np.where(stain[..., None], albedo * 0.55, albedo)
    gyh, gxh = np.gradient(h, step)
    n = np.stack([-gxh, -gyh, np.ones_like(h)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    lvec = np.asarray(light, np.float32) / np.linalg.norm(light)
    colour = albedo * (0.25 + 0.9 * np.clip(n @ lvec, 0, None))[..., None]
    pts = np.stack([X.ravel(), Y.ravel(), h.ravel()], axis=1).astype(np.float64)
    centre = np.array([15.0, 11.0, 0.0])
    f = 0.9 * W * distance_cm / 24.0                                          # A's frame: 26.7 × 20 cm of the patch
    shots = []
    for eye in (centre + [0, 0, distance_cm], centre + [0, 0, distance_cm] + np.asarray(move, np.float64) * [1, -1, -1]):
        R, c = look_at(eye, centre)
        cam = (pts - c) @ R.T
        u = f * cam[:, 0] / cam[:, 2] + W / 2.0
        v = f * cam[:, 1] / cam[:, 2] + H / 2.0
        inside = (u >= 0) & (u < W - 1) & (v >= 0) & (v < H - 1)
        pix = (np.rint(v[inside]).astype(np.int64) * W + np.rint(u[inside]).astype(np.int64))
        depth = cam[inside, 2]
        order = np.lexsort((depth, pix))                                     # nearest first per pixel
        first = order[np.unique(pix[order], return_index=True)[1]]
        img = np.zeros((H * W, 3), np.float32)
        seen = np.zeros(H * W, np.float32)
        filled = np.zeros(H * W, bool)
        img[pix[first]] = colour.reshape(-1, 3)[inside][first]
        seen[pix[first]] = h.ravel()[inside][first]
        filled[pix[first]] = True
        img = img.reshape(H, W, 3)
        holes = (~filled).reshape(H, W).astype(np.uint8)
        img = cv2.inpaint(np.clip(img, 0, 255).astype(np.uint8), holes, 2, cv2.INPAINT_TELEA).astype(np.float32)
        img = cv2.GaussianBlur(img, (0, 0), 0.6) + rng.normal(0, 2.5, img.shape)
        ok, buf = cv2.imencode(".jpg", np.clip(img, 0, 255).astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, quality])
        shots.append((cv2.imdecode(buf, cv2.IMREAD_COLOR),
                      cv2.inpaint(seen.reshape(H, W).astype(np.float32), holes, 2, cv2.INPAINT_TELEA)))
    return shots[0][0], shots[1][0], shots[0][1], shots[1][1]
