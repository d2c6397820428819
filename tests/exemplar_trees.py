"""RGBA pictures of trees to test the variations with (issue 36 part 2): a brown trunk and a crown of
leaf-coloured noise with see-through gaps and a lumpy edge, in one of three shapes (round, conifer-
like triangle, wide umbrella), every size and colour drawn from a seed. Tests use seeds they were
never tuned on."""
import cv2
import numpy as np

SHAPES = ("round", "cone", "umbrella")


def exemplar_tree(seed: int, shape: str | None = None, size: tuple[int, int] | None = None) -> tuple[np.ndarray, dict]:
    """``(rgba (H, W, 4) uint8, truth)``: ``truth`` has the trunk's box ``trunk (x0, y0, x1, y1)``
    and ``baseline`` (the crown's lowest row) in the picture's px."""
    rng = np.random.default_rng(seed)
    shape = shape or SHAPES[int(rng.integers(len(SHAPES)))]
    H, W = size or (int(rng.integers(500, 800)), int(rng.integers(400, 700)))
    img = np.zeros((H, W, 4), np.uint8)
    base = H - int(rng.integers(10, 40))
    cx = W // 2 + int(rng.integers(-20, 21))
    trunk_h = int(rng.uniform(0.15, 0.3) * H)
    trunk_w = int(rng.uniform(0.04, 0.07) * W)
    crown_h = int(rng.uniform(0.55, 0.85) * (base - trunk_h - 20))
    crown_w = int(rng.uniform(0.5, 0.9) * W) if shape != "cone" else int(rng.uniform(0.35, 0.55) * W)
    baseline = base - trunk_h
    cy = baseline - crown_h // 2
    m = np.zeros((H, W), np.uint8)
    if shape == "round":
        cv2.ellipse(m, (cx, cy), (crown_w // 2, crown_h // 2), 0, 0, 360, 1, -1)
    elif shape == "cone":
        pts = np.array([[cx, baseline - crown_h], [cx + crown_w // 2, baseline], [cx - crown_w // 2, baseline]])
        cv2.fillPoly(m, [pts.astype(np.int32)], 1)
    else:
        cv2.ellipse(m, (cx, baseline - crown_h // 3), (crown_w // 2, crown_h // 3), 0, 180, 360, 1, -1)
        cv2.rectangle(m, (cx - crown_w // 2, baseline - crown_h // 3), (cx + crown_w // 2, baseline), 1, -1)
    ys, xs = np.nonzero(m)
    edge = np.nonzero(cv2.morphologyEx(m, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)))
    for k in rng.integers(0, len(edge[0]), 50):          # lumps on the crown's edge
        cv2.circle(m, (int(edge[1][k]), int(edge[0][k])), int(rng.uniform(0.02, 0.05) * W), 1, -1)
    m[baseline + 1:] = 0                                   # the crown ends at its baseline
    gaps = cv2.GaussianBlur(rng.random((H, W)).astype(np.float32), (0, 0), 2.0)
    leaf = (m > 0) & (gaps > np.quantile(gaps[m > 0], 0.12))
    hue = rng.uniform(0.7, 1.3)
    g = 50 + 130 * rng.random((H, W))
    rgb = np.stack([g * 0.35 * hue, g, g * 0.25], -1)
    img[leaf, :3] = np.clip(rgb[leaf], 0, 255).astype(np.uint8)
    img[leaf, 3] = 255
    x0, x1 = cx - trunk_w // 2, cx + trunk_w // 2
    bark = np.array([90, 62, 40]) * rng.uniform(0.8, 1.2)
    img[baseline + 1:base + 1, x0:x1 + 1, :3] = np.clip(bark, 0, 255).astype(np.uint8)
    img[baseline + 1:base + 1, x0:x1 + 1, 3] = 255
    return img, {"trunk": (x0, baseline + 1, x1, base), "baseline": baseline, "shape": shape}
