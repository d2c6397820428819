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
