"""The 2D skeleton against the ground truth of every generated sample variant.

Bars (issue "Foundation"): traced frame-1 and all-frame chamfer ≤ 2.5% of tree height, coverage
≥ 0.75, both better than the paper-faithful skeleton; matched tips' x motion correlates with the
truth (median Pearson ≥ 0.85; ≥ 0.8 on the gentle variant) and their dominant sway frequency is
within 0.1 Hz.
"""
import os

import numpy as np
import pytest
from conftest import ALL_VARIANTS, BAR_VARIANTS
from scipy.spatial import cKDTree

from tree_from_video.core.topology import children_lists

from groundtruth import score

pytestmark = [pytest.mark.slow]


def test_every_variant_is_scored_with_both_skeletons(scores):
    assert set(scores) == set(ALL_VARIANTS)
    assert all(set(by_kind) == {"traced", "paper"} for by_kind in scores.values())


@pytest.mark.parametrize("variant", BAR_VARIANTS)
def test_traced_meets_bar_and_beats_paper(scores, variant):
    t, p = scores[variant]["traced"], scores[variant]["paper"]
    assert t.chamfer1 <= 0.025 and t.chamfer_all <= 0.025, t
    assert t.coverage >= 0.75, t
    assert t.chamfer1 < p.chamfer1 and t.chamfer_all < p.chamfer_all and t.coverage > p.coverage, (t, p)


@pytest.mark.parametrize("variant", BAR_VARIANTS)
def test_tip_motion_follows_truth(scores, variant):
    s = scores[variant]["traced"]
    assert s.tip_corr >= (0.8 if variant == "gentle" else 0.85), s
    assert s.freq_err <= 0.1, s


@pytest.mark.parametrize("variant", ALL_VARIANTS)
def test_skeleton_is_a_valid_binary_tree(runs, variant):
    sk = runs[variant]["traced"].skeleton
    par = sk.parents
    assert par[0] == -1 and (par[1:] >= 0).all() and (par[1:] < len(par)).all()
    assert max(len(c) for c in children_lists(par)) <= 2
    # every node reaches the root (no cycles)
    for n in range(len(par)):
        u, k = n, 0
        while par[u] >= 0 and k <= len(par):
            u, k = par[u], k + 1
        assert u == 0
    assert sk.nodes2d.shape == (runs[variant]["traced"].tracks.n_frames, len(par), 2)
    assert np.isfinite(sk.nodes2d).all()
    assert sk.level[0] == 0 and sk.level.max() >= 2
    # nodes in frame 1 lie inside the outline (dilated by 2 px)
    mask = runs[variant]["traced"].outline.mask
    x = np.clip(np.round(sk.nodes2d[0, :, 0]).astype(int), 0, mask.shape[1] - 1)
    y = np.clip(np.round(sk.nodes2d[0, :, 1]).astype(int), 0, mask.shape[0] - 1)
    import cv2
    grown = cv2.dilate(mask.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert grown[y, x].mean() >= 0.99


def test_dense_crown_still_gives_a_usable_skeleton(scores):
    s = scores["dense"]["traced"]
    assert s.chamfer1 <= 0.03 and s.coverage >= 0.6, s


def _first_split(parents: np.ndarray) -> int:
    ch = children_lists(parents)
    u = 0
    while len(ch[u]) == 1:
        u = ch[u][0]
    return u


def test_trunk_is_one_chain_from_the_base(runs):
    """No fake split at the base: the trunk is one chain from near the true base up to near the
    true first bifurcation (within 10% of the tree's height)."""
    for v in ("broad", "sparse", "hard", "grey", "conifer"):
        sk = runs[v]["traced"].skeleton
        truth = runs[v]["truth"]
        height = float(truth["height_px"])
        split_y = sk.nodes2d[0, _first_split(sk.parents), 1]
        true_split_y = truth["nodes2d"][0, _first_split(truth["parents"]), 1]
        assert split_y <= true_split_y + 0.1 * height, (v, split_y, true_split_y)
        assert np.linalg.norm(sk.nodes2d[0, 0] - truth["nodes2d"][0, 0]) < 0.03 * height, v


def test_no_node_follows_the_moving_object(runs):
    """Hard variant: nodes that the passer-by covers keep following their true branch."""
    e = runs["hard"]
    truth, sk = e["truth"], e["traced"].skeleton
    boxes = truth["occluder_boxes"]
    cam = truth["camera_offset"]
    on = np.flatnonzero(boxes[:, 0] >= 0)
    assert len(on) > 20
    F = sk.nodes2d.shape[0]
    img = sk.nodes2d + cam[:F, None, :]
    x0, y0, x1, y1 = (boxes[on, i][:, None] for i in range(4))
    covered = ((img[on, :, 0] >= x0 - 5) & (img[on, :, 0] <= x1 + 5)
               & (img[on, :, 1] >= y0 - 5) & (img[on, :, 1] <= y1 + 5)).any(0)
    assert covered.sum() >= 3, "the passer-by should cross some nodes"
    _, match = cKDTree(truth["nodes2d"][0]).query(sk.nodes2d[0, covered])
    d_sk = sk.nodes2d[:, covered] - sk.nodes2d[:1, covered]
    d_tr = truth["nodes2d"][:F, match] - truth["nodes2d"][:1, match]
    err = np.linalg.norm(d_sk - d_tr, axis=-1).max()
    assert err < 0.02 * float(truth["height_px"]), err


def test_barely_moves_only_on_a_still_tree(runs, tmp_path):
    """The warning names motion below what tracking resolves: not the gentle variant (its crown
    sways ~0.06 px a frame, 1.4 px a second — measurable), not broad, but a truly still tree (the
    same scene with its sway, gusts and flutter at zero: only sensor noise moves)."""
    for v in ("gentle", "broad", "sparse"):
        assert not any("barely moves" in w for w in runs[v]["traced"].warnings), (v, runs[v]["traced"].warnings)
    from tree_from_video.core.outline import load_outline
    from tree_from_video.core.reconstruct.run import track_video
    from tree_from_video.core.reconstruct.tracks import TrackParams
    from tree_from_video.core.reconstruct.video import open_video

    from samples import generate
    folder = generate("gentle", str(tmp_path / "still"), sway_scale=0.0, gust_rad=0.0, flutter_px=0.0, frames=96)
    info = open_video(os.path.join(folder, "video.mp4"), 1.0)
    outline = load_outline(os.path.join(folder, "outline.json"), info.width, info.height, 1.0)
    tracks, _ = track_video(info, outline, 0, info.frame_count, TrackParams())
    assert any("barely moves" in w for w in tracks.warnings), tracks.warnings


def test_fallback_without_any_bark_evidence(runs):
    """A crown that shows no bark at all (every pixel flickers like foliage) still gives a valid
    skeleton: the hierarchy's clusters joined to a straight trunk, with a warning."""
    import dataclasses

    from tree_from_video.core.reconstruct.trace import traced_skeleton

    res = runs["dense"]["traced"]
    no_bark = dataclasses.replace(res.maps, dark=np.zeros_like(res.maps.dark))
    sk = traced_skeleton(res.tracks, res.hierarchy, res.outline, no_bark)
    assert any("no bark" in w for w in sk.warnings)
    assert max(len(c) for c in children_lists(sk.parents)) <= 2
    truth = runs["dense"]["truth"]
    s = score(sk.parents, sk.nodes2d, truth)
    assert s.chamfer1 <= 0.04 and s.coverage >= 0.5, s
    print(f"fallback on dense: {s}")
    # the trunk climbs straight from the base, and does climb
    ch = children_lists(sk.parents)
    chain = [0]
    while len(ch[chain[-1]]) == 1:
        chain.append(ch[chain[-1]][0])
    xy = sk.nodes2d[0, chain]
    h = float(truth["height_px"])
    assert np.ptp(xy[:, 0]) < 0.05 * h and xy[0, 1] - xy[-1, 1] > 0.15 * h, xy


def _camera_shift(tracks, size):
    """``(F, 2)`` px: where the image centre of each frame lands in frame 1, minus the centre (the
    estimated camera translation)."""
    from tree_from_video.core.reconstruct.tracks import apply_affine
    c = np.array([size[0] / 2, size[1] / 2], float)
    return np.array([c - apply_affine(m.astype(float), c) for m in tracks.camera])


def test_camera_motion_only_where_the_background_moves(runs, tmp_path):
    """Tripod variants get no camera motion at all (was up to 0.1 px here, 0.6 px of drift under
    flicker); the hand-held one (shake + drift up to 7 px, a passer-by) is recovered: 95 % of frames
    within 0.3 px of the truth, every frame within 0.6 px."""
    for v in ("broad", "conifer", "sparse", "gentle", "grey", "dense"):
        tr = runs[v]["traced"].tracks
        assert np.abs(_camera_shift(tr, tr.size)).max() <= 0.3, v
    tr = runs["hard"]["traced"].tracks
    err = np.linalg.norm(_camera_shift(tr, tr.size) - runs["hard"]["truth"]["camera_offset"][:tr.n_frames], axis=1)
    assert np.percentile(err, 95) <= 0.3 and err.max() <= 0.6, (np.percentile(err, 95), err.max())
    from tree_from_video.core.outline import load_outline
    from tree_from_video.core.reconstruct.run import track_video
    from tree_from_video.core.reconstruct.tracks import TrackParams
    from tree_from_video.core.reconstruct.video import open_video

    from samples import generate
    folder = generate("flicker", str(tmp_path / "flicker"), frames=120)        # ±15 % light, cloud shadows
    info = open_video(os.path.join(folder, "video.mp4"), 1.0)
    outline = load_outline(os.path.join(folder, "outline.json"), info.width, info.height, 1.0)
    tracks, _ = track_video(info, outline, 0, info.frame_count, TrackParams())
    assert np.abs(_camera_shift(tracks, tracks.size)).max() <= 0.3
