"""The leaves' colour of a tree from one photo is its foliage's, not its trunk's (issue 35; a real
photo of a western red cedar: an orange trunk up through a sunlit crown, its shaded foliage missed
by frame 1's colour test, gave tan leaves, hue 46°, for a yellow-green crown, hue 70°): a drawn
crown, mostly shaded green with sunlit yellow-green tufts, an orange trunk up through it, against a
blue sky; the leaves come out green, within 25° of the crown's own hue."""
import colorsys
import json

import cv2
import numpy as np

from tree_from_video.core import pipeline
from tree_from_video.core.generate.photo import PhotoMotion

from exemplar_trees import exemplar_tree
from samples import plain_settings


def hue(rgb) -> float:
    return 360.0 * colorsys.rgb_to_hsv(*np.clip(np.asarray(rgb, float), 0, 1))[0]


def test_a_trunk_up_through_a_sunlit_crown_keeps_the_leaves_green(tmp_path):
    rgba, truth = exemplar_tree(417, "round", size=(600, 420))
    h, w = rgba.shape[:2]
    rng = np.random.default_rng(417)
    crown = rgba[..., 3] >= 128
    sun = cv2.GaussianBlur(rng.standard_normal((h, w)).astype(np.float32), (0, 0), 6) > 0.6      # sunlit tufts
    leaf = np.where(sun[..., None], [150, 165, 60], [55, 85, 35]) * rng.uniform(0.85, 1.15, (h, w, 1))
    x0, _, x1, _ = truth["trunk"]
    cx, half = (x0 + x1) // 2, max(6, (x1 - x0) // 2)
    top = int(np.nonzero(crown.any(1))[0][0] + 0.2 * crown.any(1).sum())
    trunk = np.zeros((h, w), bool)
    trunk[top:, cx - half:cx + half] = True                             # up through the crown
    trunk &= crown | (np.arange(h)[:, None] > np.nonzero(crown.any(1))[0][-1])
    sky = np.array([235, 190, 120]) - np.linspace(0, 40, h)[:, None, None]           # BGR, a blue sky
    img = np.where(crown[..., None], leaf[..., ::-1], sky)
    img = np.where(trunk[..., None], np.array([70, 120, 200]) * rng.uniform(0.8, 1.1, (h, w, 1)), img)
    # young trees of the shaded foliage's green below the crown, beside the trunk, as in the photo
    bush = np.zeros((h, w), np.uint8)
    for bx in (cx - 3 * half - 40, cx + 3 * half + 40):
        cv2.ellipse(bush, (int(bx), h - 30), (45, 90), 0, 0, 360, 1, -1)
    bush = (bush > 0) & ~crown & ~trunk
    img = np.where(bush[..., None], np.array([35, 85, 55]) * rng.uniform(0.85, 1.15, (h, w, 1)), img)
    photo = np.clip(img + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)
    path = str(tmp_path / "cedar.png")
    cv2.imwrite(path, photo)
    ys, xs = np.nonzero(crown | trunk)          # the outline round the tree, the young trees left out
    hull = cv2.convexHull(np.stack([xs, ys], 1).astype(np.int32))[:, 0]
    (tmp_path / "outline.json").write_text(json.dumps(hull.tolist()))
    s = plain_settings()
    res = pipeline.run(path, str(tmp_path / "outline.json"), s)
    tree = pipeline.build_3d(res, s, photo=PhotoMotion(seconds=1.0))
    got = np.asarray(tree.meta["leaf_colour"]["colour"])
    foliage = np.median(photo[crown & ~trunk][:, ::-1] / 255.0, 0)
    print(f"\nleaf colour {got.round(3)} (hue {hue(got):.0f}°), the foliage's median {foliage.round(3)} "
          f"(hue {hue(foliage):.0f}°), the trunk's hue {hue(np.array([200, 120, 70]) / 255):.0f}°; "
          f"{tree.meta['leaf_colour']['why']}")
    assert abs(hue(got) - hue(foliage)) <= 25.0
