"""Random blurred textures and their sub-pixel shifts: images whose motion is known exactly, for the
tracker's hand cases."""
import cv2
import numpy as np


def texture(seed: int = 1, h: int = 240, w: int = 320) -> np.ndarray:
    """``(h, w)`` uint8: uniform noise on a 4× coarser grid, cubic upsampled and blurred (σ 1 px)."""
    rng = np.random.default_rng(seed)
    img = rng.uniform(0, 255, (h // 4, w // 4)).astype(np.float32)
    img = cv2.resize(img, (w, h), interpolation=cv2.INTER_CUBIC)
    return np.clip(cv2.GaussianBlur(img, (0, 0), 1.0), 0, 255).astype(np.uint8)


def shifted(img: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``img`` moved by (dx, dy) px (cubic, reflected border)."""
    m = np.array([[1, 0, dx], [0, 1, dy]], np.float64)
    return cv2.warpAffine(img, m, (img.shape[1], img.shape[0]), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
