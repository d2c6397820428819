"""Frame 1's foreground (core/reconstruct/foreground.py) and the leaf clusters' cover of it
(core/detail/leaf_cover.py), on hand-made frames whose answer is known."""
import cv2
import numpy as np

from tree_from_video.core.detail.leaf_cover import card_footprint, uncovered_sites
from tree_from_video.core.reconstruct.branch_fit import tree_map
from tree_from_video.core.reconstruct.foreground import contour_segments, foreground


def _backlit(h=240, w=320, seed=0):
    """A dark crown (a disk with a few sky holes) on a trunk against a bright sky, the ground in
    shadow as dark as the crown: the outline, the true mask and the frame."""
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w, 3), np.float32)
    img[:] = (232, 234, 236)                                   # overcast sky (BGR)
    img[int(0.8 * h):] = (16, 22, 18)                          # shadowed ground
    truth = np.zeros((h, w), np.uint8)
    cv2.circle(truth, (w // 2, int(0.38 * h)), int(0.3 * h), 1, -1)
    cv2.rectangle(truth, (w // 2 - 6, int(0.6 * h)), (w // 2 + 6, int(0.8 * h)), 1, -1)
    for _ in range(4):                                         # sky seen through the crown
        cv2.circle(truth, (int(w / 2 + rng.integers(-40, 40)), int(0.38 * h + rng.integers(-30, 30))), 6, 0, -1)
    truth = truth.astype(bool)
    img[truth] = (14, 24, 12)
    img += rng.normal(0, 2.0, img.shape)
    outline = np.zeros((h, w), np.uint8)
    cv2.ellipse(outline, (w // 2, int(0.45 * h)), (int(0.36 * h), int(0.42 * h)), 0, 0, 360, 1, -1)
    return outline.astype(bool), truth, np.clip(img, 0, 255).astype(np.uint8)


def _iou(a, b):
    return (a & b).sum() / max((a | b).sum(), 1)


def test_the_graph_cut_finds_a_backlit_crown_the_colour_test_loses_against_dark_ground():
    outline, truth, img = _backlit()
    colour = tree_map(img, outline).tree & outline
    fg = foreground(img, outline)
    assert fg is not None and fg.method.startswith("graph cut")
    t = truth & outline
    print(f"\nIoU: colour test {_iou(colour, t):.3f}, graph cut {_iou(fg.mask, t):.3f}")
    assert _iou(fg.mask, t) >= 0.95
    assert _iou(fg.mask, t) > _iou(colour, t) + 0.1
    assert fg.share == fg.mask.sum() / outline.sum()


def test_an_outline_filling_the_frame_has_no_background_to_compare_with():
    img = np.full((60, 80, 3), 90, np.uint8)
    assert foreground(img, np.ones((60, 80), bool)) is None


def test_a_card_footprint_lies_within_the_cluster_and_grows_with_its_size():
    base, scale = np.array([100.0, 180.0]), 0.01           # 1 cm per px; the base at (100, 180)
    pos = np.array([[0.0, 0.0, 1.0]])                      # 1 m up: image (100, 80)
    axis = np.array([[0.0, 0.0, 1.0]])
    small = card_footprint((200, 200), pos, axis, np.array([0.5]), 0.2, 0.11, 16, 0, base, scale)
    full = card_footprint((200, 200), pos, axis, np.array([1.0]), 0.2, 0.11, 16, 0, base, scale)
    ys, xs = np.nonzero(full)
    assert np.hypot(xs - 100, ys - 80).max() <= 20 + 1    # within the 0.2 m radius (+1 px of raster)
    ys, xs = np.nonzero(small)
    assert 0 < small.sum() < full.sum() and np.hypot(xs - 100, ys - 80).max() <= 10 + 1   # half the size
    assert 0.15 <= full.sum() / (np.pi * 20 ** 2) <= 1.0    # 16 blades cover part of the disk


def test_uncovered_sites_go_where_the_target_is_bare_one_per_cell():
    target = np.zeros((100, 100), bool)
    target[20:80, 20:80] = True
    covered = np.zeros_like(target)
    covered[:, :50] = True                                 # the left half is covered
    sites = uncovered_sites(target, covered, 10.0)
    assert len(sites) > 0 and (sites[:, 0] >= 50).all()
    cells = {(int(x // 10), int(y // 10)) for x, y in sites}
    assert len(cells) == len(sites)                        # one per 10 px cell
    assert len(uncovered_sites(target, target, 10.0)) == 0


def test_contour_segments_trace_the_mask_edge_in_pairs():
    m = np.zeros((50, 60), bool)
    m[10:30, 20:45] = True
    seg = contour_segments(m)
    assert len(seg) % 2 == 0 and len(seg) >= 8
    on_edge = ((seg[:, 0] == 20) | (seg[:, 0] == 44)) | ((seg[:, 1] == 10) | (seg[:, 1] == 29))
    assert on_edge.all()
    assert len(contour_segments(np.zeros((5, 5), bool))) == 0


def _real_crown(h=360, w=640, seed=0):
    """What real footage gives (issue 31): a crown of sub-pixel leaves (a texture of light and dark
    greens, no leaf larger than a pixel) against a smooth overcast sky, a second tree of the same
    foliage beside it and a grassy field under it, all three in the ring round a loosely drawn
    outline, which also cuts through the crown's edge. The outline, the true mask inside it and
    the frame."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.zeros((h, w, 3), np.float32)
    img[:] = np.stack([218 + 10 * yy / h, 222 + 8 * yy / h, 226 + 6 * yy / h], -1)   # overcast sky (BGR)

    def foliage(m):
        t = rng.random(m.sum())[:, None]
        dark, light = np.array([30, 70, 40]), np.array([90, 170, 130])
        img[m] = dark + t * (light - dark) + rng.normal(0, 6, (m.sum(), 3))

    field = yy > 0.86 * h
    foliage(field)
    img[field] *= [0.8, 1.1, 0.9]
    crown = np.zeros((h, w), np.uint8)
    cv2.ellipse(crown, (w // 2 - 40, int(0.45 * h)), (int(0.36 * w / 2 * 1.1), int(0.38 * h)), 0, 0, 360, 1, -1)
    cv2.rectangle(crown, (w // 2 - 52, int(0.8 * h)), (w // 2 - 28, int(0.87 * h)), 1, -1)
    for _ in range(25):                                             # sky seen through the crown
        cv2.circle(crown, (int(w / 2 - 40 + rng.integers(-120, 120)), int(0.45 * h + rng.integers(-100, 100))),
                   int(rng.integers(3, 9)), 0, -1)
    crown = crown.astype(bool)
    neighbour = np.zeros((h, w), np.uint8)
    cv2.ellipse(neighbour, (int(0.86 * w), int(0.55 * h)), (int(0.13 * w), int(0.33 * h)), 0, 0, 360, 1, -1)
    foliage(neighbour.astype(bool) & ~crown)
    foliage(crown)
    outline = np.zeros((h, w), np.uint8)
    cv2.ellipse(outline, (w // 2 - 30, int(0.47 * h)), (int(0.36 * w / 2 * 1.05), int(0.41 * h)), 0, 0, 360, 1, -1)
    outline = outline.astype(bool)
    return outline, crown & outline, np.clip(img, 0, 255).astype(np.uint8)


def test_a_real_crown_whose_ring_holds_foliage_is_found_by_its_texture():
    """Issue 31: the nearest-sample colour test finds every leaf colour in a ring that crosses the
    crown's edge, a second tree and a field, so the cut fell back to the whole ring's test and kept
    nothing (IoU 0.00–0.01 on two real dense crowns; on this frame 0.04 before the texture ratio).
    The inside-vs-ring histogram of colour and texture seeds the cut instead: IoU ≥ 0.85 on three
    seeds, and the outline's sky stays background."""
    for seed in range(3):
        outline, truth, img = _real_crown(seed=seed)
        fg = foreground(img, outline)
        iou = _iou(fg.mask, truth)
        sky = outline & ~truth
        print(f"\nseed {seed}: {fg.method}, IoU {iou:.3f}, sky called tree {(fg.mask & sky).sum() / sky.sum():.3f}")
        assert iou >= 0.85, (seed, fg.method, iou)
        assert (fg.mask & sky).sum() / sky.sum() <= 0.25


def test_the_ratio_map_is_the_inside_share_of_a_colour_and_texture_bin():
    """ratio_map = h_in / (h_in + h_ring) on a hand case: a flat sky all round, a textured crown in
    the middle of the outline: the crown's pixels are ~1 (never in the ring); a flat sky pixel is
    f / (f + 1), f the share of the inside that is flat sky (the ring is all flat sky)."""
    from tree_from_video.core.reconstruct.branch_fit import frame_lab
    from tree_from_video.core.reconstruct.foreground import local_texture, ratio_map
    rng = np.random.default_rng(1)
    img = np.full((200, 200, 3), 220, np.uint8)
    outline = np.zeros((200, 200), bool)
    outline[40:160, 40:160] = True
    crown = np.zeros_like(outline)
    crown[70:130, 70:130] = True
    img[crown] = rng.integers(20, 120, (crown.sum(), 3))
    p = ratio_map(img, outline)
    flat = local_texture(frame_lab(img)[..., 0]) < 0.01
    f = (flat & outline).sum() / outline.sum()
    assert np.median(p[75:125, 75:125]) > 0.95
    assert abs(np.median(p[45:60, 45:155]) - f / (f + 1)) < 0.02
