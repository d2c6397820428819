"""Frame 1's own pixels in the trace (core/frame_evidence.py): bark coloured like the trunk,
background, and the traced skeleton against the truth with and without them."""
import cv2
import numpy as np
import pytest

from tree_from_video.core.reconstruct.branch_fit import TreeMap
from tree_from_video.core.reconstruct.frame_evidence import frame_evidence
from tree_from_video.core.reconstruct.trace import TraceParams, traced_skeleton

from groundtruth import score

pytestmark = [pytest.mark.bpy53]

SKY, BARK, LEAF = (225, 170, 110), (40, 70, 110), (50, 150, 60)       # BGR


def _frame(leaf=LEAF, seed=0):
    """A 200×160 frame: sky with mild noise, a textured trunk (rows 130-190, 8 px wide), a 4 px
    branch from the trunk's top up to the right, a 16 px leaf blob on the left; the outline a
    rectangle with sky around it. Returns (frame BGR, mask, trunk mask, the branch's centre line,
    blob mask). (Branches of 1-2 px mix with the sky in every pixel: their colour is no bark's.)"""
    rng = np.random.default_rng(seed)
    img = np.empty((200, 160, 3), np.float32)
    img[:] = SKY
    img += rng.normal(0, 1.5, img.shape)
    trunk = np.zeros((200, 160), np.uint8)
    cv2.rectangle(trunk, (76, 130), (83, 190), 1, -1)
    thin = np.zeros_like(trunk)
    cv2.line(thin, (80, 130), (130, 40), 1, 4)
    axis = np.zeros_like(trunk)
    cv2.line(axis, (80, 130), (130, 40), 1, 1)
    blob = np.zeros_like(trunk)
    cv2.circle(blob, (45, 70), 8, 1, -1)
    wood = (trunk | thin) > 0
    img[wood] = np.asarray(BARK, np.float32) + rng.normal(0, 6, (int(wood.sum()), 3))
    img[blob > 0] = leaf
    mask = np.zeros((200, 160), bool)
    mask[20:192, 20:140] = True
    return np.clip(img, 0, 255).astype(np.uint8), mask, trunk > 0, axis > 0, blob > 0


def test_tree_level_by_hand():
    """T = clip((dist − floor) / (2 (thr − floor)), 0, 1): 0 at the floor, ½ at the threshold."""
    tm = TreeMap(np.array([[2.0, 6.0, 10.0, 1.0, 20.0]], np.float32), thr=6.0, floor=2.0)
    np.testing.assert_allclose(tm.level(), [[0.0, 0.5, 1.0, 0.0, 1.0]])


def test_thin_bark_is_found_and_leaves_and_sky_are_not():
    img, mask, trunk, thin, blob = _frame()
    fe = frame_evidence(img, mask, trunk)
    assert fe is not None and fe.bark is not None
    assert np.median(fe.bark[thin]) > 0.9
    assert fe.bark[blob].max() == 0.0                 # green is no bark colour
    sky = mask & ~cv2.dilate((trunk | thin | blob).astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
    assert fe.bark[sky].max() == 0.0
    assert fe.background[sky].mean() > 0.95
    assert fe.background[cv2.erode(trunk.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0].max() < 0.05
    assert 0.0 < fe.bark_share < 0.05


def test_colour_says_nothing_when_the_crown_is_bark_coloured():
    """Leaves as dark and brown as the bark, and most of the crown: no bark map, only background."""
    img, mask, trunk, _, _ = _frame()
    img[30:120, 30:130] = BARK                       # a crown of bark-coloured foliage
    fe = frame_evidence(img, mask, trunk)
    assert fe.bark is None and fe.bark_share > 0.3
    assert fe.background[40:110, 40:120].max() < 0.05


def test_no_trunk_or_no_background_band():
    img, mask, trunk, _, _ = _frame()
    fe = frame_evidence(img, mask, np.zeros_like(trunk))
    assert fe.bark is None and np.isnan(fe.bark_share) and fe.background is not None
    assert frame_evidence(img, np.ones_like(mask), trunk) is None      # the outline fills the frame


@pytest.mark.parametrize("variant", ["sparse", "broad"])
def test_frame1_brings_the_traced_skeleton_closer_to_the_truth(runs, variant):
    """Measured chamfer (% of height) without → with frame 1: sparse 0.95 → 0.49 (a bare crown
    whose thin limbs sway more than their width), broad 1.06 → 0.88."""
    res = runs[variant]["traced"]
    truth = runs[variant]["truth"]
    without = traced_skeleton(res.tracks, res.hierarchy, res.outline, res.maps, TraceParams(frame1=False))
    a = score(without.parents, without.nodes2d, truth)
    b = score(res.skeleton.parents, res.skeleton.nodes2d, truth)
    print(f"\n{variant}: without frame 1 {a}\n{variant}: with frame 1    {b}")
    assert b.chamfer1 < (0.7 if variant == "sparse" else 0.95) * a.chamfer1
    assert b.coverage >= a.coverage - 0.01


def test_stem_core_is_the_middle_half_of_the_outlines_foot():
    """An outline drawn round a crown narrowing to a 20 px stem over its lowest 40 rows: the core is
    the middle half of those rows in its lowest quarter (10 px); an outline as wide at its foot as
    anywhere has none."""
    from tree_from_video.core.reconstruct.frame_evidence import stem_core
    mask = np.zeros((200, 160), bool)
    cv2.circle(mask.view(np.uint8), (80, 80), 60, 1, -1)
    mask[140:190, 70:90] = True                          # the stem, rows 141-189 below the circle
    core = stem_core(mask)
    rows = np.flatnonzero(core.any(1))
    # the lowest quarter of the height (20-189): rows above 189 − 42.5, all of them the stem's
    assert rows.min() == 147 and rows.max() == 189 and len(rows) == 43
    assert set(core.sum(1)[rows]) == {10} and core[rows][:, 75:85].all()       # |x − 79.5| ≤ 5
    box = np.zeros((200, 160), bool)
    box[20:192, 20:140] = True
    assert stem_core(box) is None


def test_a_bright_trunk_takes_its_colour_from_the_stem():
    """A sunlit trunk (brighter than its crown) with dark young trees at its foot: the trunk pixels
    the clip's dark ridges give are the young trees' edges, whose colour marks none of the stem's
    middle; the bark colour then comes from the stem, and marks the trunk, not the young trees."""
    img = np.empty((200, 160, 3), np.float32)
    img[:] = SKY
    rng = np.random.default_rng(3)
    img += rng.normal(0, 1.5, img.shape)
    crown = np.zeros((200, 160), np.uint8)
    cv2.circle(crown, (80, 70), 55, 1, -1)
    img[crown > 0] = (40, 90, 50)
    img[60:195, 72:90] = (80, 140, 215)                   # the orange trunk, up into the crown
    bush = np.zeros((200, 160), np.uint8)
    cv2.ellipse(bush, (62, 190), (14, 30), 0, 0, 360, 1, -1)
    cv2.ellipse(bush, (100, 190), (14, 30), 0, 0, 360, 1, -1)
    bush[:, 72:90] = 0
    img[bush > 0] = (35, 80, 45)
    img = np.clip(img + rng.normal(0, 2, img.shape), 0, 255).astype(np.uint8)
    mask = crown > 0
    mask[120:195, 66:96] = True
    edges = (cv2.dilate(bush, np.ones((3, 3), np.uint8)) > 0) & (bush == 0) | (bush > 0) & (np.arange(160) < 73)
    fe = frame_evidence(img, mask, edges & (np.arange(200)[:, None] > 150))
    assert fe.stem is not None and fe.bark is not None
    assert fe.bark[150:195, 74:88].mean() > 0.8          # the trunk
    assert fe.bark[bush > 0].mean() < 0.1 and fe.bark[crown > 0][:100].mean() < 0.1
    assert 16 <= fe.trunk_width <= 20
