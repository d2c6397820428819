"""Leaf seeds: the dark/bright split against known leaves, and their 3D placement."""
import cv2
import numpy as np

from tree_from_video.core import leaves, lift3d
from tree_from_video.core.tracks import TrackParams, detect_corners


def _leaf_frame(seed=0, n=160, size=(360, 480)):
    """A frame of random leaf ellipses, each dark (shadowed) or bright (sunlit), over sky; returns
    the image, a label image (1 dark leaf, 2 bright leaf) and the leaves' mask."""
    rng = np.random.default_rng(seed)
    h, w = size
    img = np.full((h, w), 200, np.uint8)
    lab = np.zeros((h, w), np.uint8)
    for _ in range(n):
        c = (int(rng.uniform(60, w - 60)), int(rng.uniform(40, h - 40)))
        ax = (int(rng.uniform(5, 10)), int(rng.uniform(3, 6)))
        ang = float(rng.uniform(0, 180))
        dark = rng.random() < 0.5
        grey = int(rng.uniform(40, 85) if dark else rng.uniform(120, 170))
        cv2.ellipse(img, c, ax, ang, 0, 360, grey, -1)
        cv2.ellipse(lab, c, ax, ang, 0, 360, 1 if dark else 2, -1)
    img = np.clip(img + rng.normal(0, 3, img.shape), 0, 255).astype(np.uint8)
    return img, lab


def test_dark_bright_split_matches_known_leaves():
    img, lab = _leaf_frame()
    pts = detect_corners(img, lab > 0, TrackParams())
    x = np.round(pts[:, 0]).astype(int)
    y = np.round(pts[:, 1]).astype(int)
    truth_dark = lab[y, x] == 1
    on_leaf = lab[y, x] > 0
    dark = leaves.split_dark_bright(leaves.seed_intensity(img, pts))
    agree = (dark[on_leaf] == truth_dark[on_leaf]).mean()
    print(f"{on_leaf.sum()} seeds on leaves, split agrees with the truth on {100 * agree:.1f}%")
    assert on_leaf.sum() > 100 and agree >= 0.9


def test_split_is_halves_by_the_median():
    dark = leaves.split_dark_bright(np.array([10.0, 200, 50, 180, 90, 120]))
    assert dark.tolist() == [True, False, True, False, True, False]


def test_seed_depth_goes_back_for_dark_and_front_for_bright(runs):
    res = runs["broad"]["traced"]
    sk = res.skeleton
    L = lift3d.lift(sk, res.outline)
    from tree_from_video.core.video import iter_frames
    gray = cv2.cvtColor(next(iter_frames(res.info, res.start, res.start + 1)), cv2.COLOR_BGR2GRAY)
    s = leaves.leaf_seeds(res.tracks.points[0], gray, sk.nodes2d[0], L.nodes, sk.nodes2d[0, 0].astype(float),
                          L.envelope)
    at_seed = s.pos3d.astype(float).copy()
    limit = L.envelope.depth_limit(at_seed)
    y0 = np.clip(L.nodes[s.node, 1], -limit, limit)             # the node's depth inside Ω at the seed
    assert np.all(s.pos3d[s.dark, 1] >= y0[s.dark] - 1e-3)          # dark: toward the back
    assert np.all(s.pos3d[~s.dark, 1] <= y0[~s.dark] + 1e-3)        # bright: toward the front
    assert L.envelope.contains(s.pos3d.astype(float), tol=1.0).mean() > 0.95
    assert abs(s.dark.mean() - 0.5) < 0.02
