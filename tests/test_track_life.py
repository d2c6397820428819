"""Tracks that live through the clip (issue 18): re-detection where tracks have thinned, late tracks
matched to nodes where they were born, the crown moving as one is never a jerk, and the node motion
confidence on hand cases."""
import numpy as np
import pytest
from textures import shifted, texture

from tree_from_video.core.outline import polygon_outline
from tree_from_video.core.reconstruct import node_motion as nm
from tree_from_video.core.reconstruct import tracks as trk

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

H, W = 240, 320
BOX = np.array([[60, 40], [260, 40], [260, 200], [60, 200]], float)


def _scene(offsets, scramble_from=None, seed=1):
    """Frames of a texture translated by ``offsets (F, 2)``; from frame ``scramble_from`` on, the left
    half of the box shows a new texture every frame (leaves turning: nothing there can be followed)."""
    base = texture(seed)
    frames = []
    for t, (dx, dy) in enumerate(offsets):
        f = shifted(base, dx, dy)
        if scramble_from is not None and t >= scramble_from:
            noise = shifted(texture(1000 + t), dx, dy)
            f[:, :160] = noise[:, :160]
        frames.append(f)
    return frames


def _track(frames, **kw):
    outline = polygon_outline(BOX, W, H)
    params = trk.TrackParams(stabilize=False, **kw)
    tr = trk.Tracker(frames[0], outline, 24.0, 0, params)
    for f in frames[1:]:
        tr.feed(f)
    return tr.result()


def test_thinned_region_is_refilled_and_late_tracks_know_their_frame1_reference():
    F = 30
    t = np.arange(F)
    offsets = np.stack([3.0 * np.sin(2 * np.pi * t / 24), 1.5 * np.sin(2 * np.pi * t / 17)], 1)
    # the whole box moves; at frame 10 the left half shows another texture (the leaves have turned, the
    # seam moves with the box): its tracks die and must come back
    base = texture(1)
    turned = base.copy()
    turned[:, :160] = texture(77)[:, :160]
    frames = [shifted(base if k < 10 else turned, dx, dy) for k, (dx, dy) in enumerate(offsets)]
    tracks = _track(frames)
    first = tracks.initial()
    left = tracks.points[0, :, 0] < 150
    n_left0 = int((tracks.valid[0] & left).sum())
    assert n_left0 > 30
    # without re-detection the left half stays empty
    plain = _track(frames, redetect_every=0)
    left_p = plain.points[0, :, 0] < 150
    assert (plain.valid[-1] & left_p).sum() < 0.1 * n_left0
    # with it, the left half is at least half as full as in frame 1 at the end, by tracks born late
    late = np.setdiff1d(np.arange(tracks.points.shape[1]), first)
    assert (tracks.valid[-1] & left).sum() >= 0.5 * n_left0
    assert len(late) > 0 and not tracks.valid[0, late].any()
    # a late track that lives on has as frame-1 row where it is minus the crown's displacement (known)
    late = late[tracks.valid[-1, late]]
    born = np.argmax(tracks.valid[:, late], axis=0)
    pos = tracks.points[born, late]
    err = np.linalg.norm(tracks.points[0, late] - (pos - offsets[born]), axis=1)
    assert len(late) > 30 and np.median(err) < 0.3 and np.percentile(err, 90) < 1.0
    # before its birth a track is invalid and sits at its reference
    k = late[0]
    assert not tracks.valid[: born[0], k].any()
    assert np.allclose(tracks.points[: born[0], k], tracks.points[0, k])


def test_a_crown_moving_as_one_is_never_a_jerk():
    F = 20
    x = np.concatenate([np.zeros(6), 4.0 * np.arange(1, F - 5)])   # still, then 4 px per frame at once
    offsets = np.stack([x, np.zeros(F)], 1)
    tracks = _track(_scene(offsets), redetect_every=0)
    first = tracks.initial()
    inside = (tracks.points[0, first, 0] > 70) & (tracks.points[0, first, 0] < 250)
    assert tracks.valid[-1, first[inside]].mean() > 0.9
    d = tracks.points[-1, first[inside]] - tracks.points[0, first[inside]]
    ok = tracks.valid[-1, first[inside]]
    assert np.median(d[ok, 0]) == pytest.approx(x[-1], abs=0.2)


def _hand_tracks(points, valid):
    F, P = valid.shape
    return trk.Tracks(np.asarray(points, np.float32), np.asarray(valid, bool), np.zeros((F, 2, 3), np.float32),
                      np.zeros(P, np.float32), 24.0, 0, (100, 100))


def test_late_track_is_matched_where_it_was_born_not_through_its_reference():
    F = 10
    pts = np.zeros((F, 3, 2))
    valid = np.zeros((F, 3), bool)
    pts[:, 0] = np.stack([np.arange(F) * 1.0, np.zeros(F)], 1)          # by node A, moving +x
    valid[:, 0] = True
    pts[:, 1] = [20.0, 0.0]                                              # by node B, still, lost at 5
    valid[:6, 1] = True
    pts[:, 2] = [0.0, 0.0]                                               # born at 5 by node B, moving +y;
    pts[5:, 2] = np.stack([np.full(F - 5, 20.0), np.arange(F - 5) * 1.0], 1)   # its frame-1 row (0, 0)
    valid[5:, 2] = True                                                  # would put it by node A
    nodes = np.array([[0.0, 0.0], [20.0, 0.0]])
    m = nm.follow_tracks(nodes, _hand_tracks(pts, valid), scale=2.0, k_nearest=0)
    assert m.nodes[-1, 0] == pytest.approx([F - 1, 0.0], abs=1e-4)      # A: track 0 only
    assert m.nodes[-1, 1] == pytest.approx([20.0, F - 1 - 5], abs=1e-4)  # B: still, then track 2's +y


def test_a_node_is_anchored_at_its_tracks_births_and_does_not_keep_a_lost_tracks_error():
    """eq. d_n(t) (node_motion's docstring) by hand: tracks 0 and 1 stand on the node; track 1 jumps
    2 px in frame 1 (a leaf turning) and is lost after frame 3; track 2 is born on the node in frame
    6. While track 1 lives the node is off by the mean, +1 px; once it is lost the node is exactly
    track 0 again (a chain of mean steps kept the +1 for ever), and track 2 adds its move since its
    birth to the node's displacement then."""
    F = 10
    x0 = np.array([0, 1, 2, 1, 0, 1, 2, 3, 2, 1], float)           # the node's true x
    pts = np.zeros((F, 3, 2))
    valid = np.zeros((F, 3), bool)
    pts[:, 0, 0] = x0
    valid[:, 0] = True
    pts[:, 1, 0] = x0 + np.where(np.arange(F) >= 1, 2.0, 0.0)
    valid[:4, 1] = True
    pts[6:, 2] = np.stack([x0[6:] + 0.3, np.full(F - 6, 0.2)], 1)    # born 0.3 px right of the node
    valid[6:, 2] = True
    m = nm.follow_tracks(np.array([[0.0, 0.0]]), _hand_tracks(pts, valid), scale=2.0)
    want = x0 + np.where((np.arange(F) >= 1) & (np.arange(F) <= 3), 1.0, 0.0)
    assert m.nodes[:, 0, 0] == pytest.approx(want, abs=1e-5)
    assert m.nodes[:, 0, 1] == pytest.approx(np.zeros(F), abs=1e-5)


def test_a_column_holding_two_tracks_moves_each_node_by_its_own():
    """Once every column is used a new track takes a lost late track's column (Tracks' docstring):
    the column's second track, born by node B, moves B, and no longer A, by whose first track it
    stood (A then follows the crown: three still tracks far from both)."""
    F = 12
    pts = np.zeros((F, 4, 2))
    valid = np.zeros((F, 4), bool)
    pts[:, :3] = [[50.0, 50.0], [55.0, 50.0], [50.0, 55.0]]               # the still crown
    valid[:, :3] = True
    pts[:4, 3] = np.stack([np.arange(4) * 1.0, np.zeros(4)], 1)          # by A, +x, lost after frame 3
    valid[:4, 3] = True
    pts[6:, 3] = np.stack([np.full(F - 6, 100.0), np.arange(F - 6) * 1.0], 1)  # then by B from 6, +y
    valid[6:, 3] = True
    nodes = np.array([[0.0, 0.0], [100.0, 0.0]])
    tr = _hand_tracks(pts, valid)
    m = nm.follow_tracks(nodes, tr, scale=2.0, k_nearest=0)
    assert m.nodes[3, 0] == pytest.approx([3.0, 0.0], abs=1e-4)          # A followed the first track
    assert m.nodes[-1, 0] == pytest.approx([3.0, 0.0], abs=1e-4)         # … then the still crown
    assert m.nodes[-1, 1] == pytest.approx([100.0, F - 1 - 6], abs=1e-4)  # B: the second track's +y
    assert (m.confidence[7:, 0] == 0).all() and (m.confidence[7:, 1] > 0.3).all()
    assert tr.last_span()[:, 3].tolist() == [False] * 6 + [True] * (F - 6)


def test_a_full_tracker_reuses_lost_late_columns_and_keeps_the_crown_tracked():
    """The left half of the crown turns its leaves every 5 frames (its tracks die, refills replace
    them: ~500 new tracks every 5 frames); with room for 600 late tracks the tracker reuses their
    columns once they are lost: the array stays 600 columns wider than frame 1's, frame 1's tracks
    keep theirs, the left half is still tracked at the end, and each reused column's last track
    knows its frame-1 reference."""
    F = 60
    t = np.arange(F)
    offsets = np.stack([3.0 * np.sin(2 * np.pi * t / 24), 1.5 * np.sin(2 * np.pi * t / 17)], 1)
    base = texture(1)
    frames = []
    for k, (dx, dy) in enumerate(offsets):
        f = base.copy()
        f[:, :160] = texture(300 + k // 5)[:, :160]
        frames.append(shifted(f, dx, dy))
    first = _track(frames[:1] * 2)
    n0 = len(first.initial())
    tracks = _track(frames, max_tracks=n0 + 600)
    P = tracks.points.shape[1]
    assert P == n0 + 600
    born = tracks.valid.copy()
    born[1:] &= ~tracks.valid[:-1]
    assert (born[:, :n0].sum(0) == tracks.valid[0, :n0]).all()          # frame 1's columns: one track
    reused = np.flatnonzero(born[:, n0:].sum(0) > 1) + n0
    assert len(reused) >= 100 and born.sum() > P + 600
    left = tracks.points[-1, :, 0] < 150
    n_left0 = int((tracks.valid[0] & (tracks.points[0, :, 0] < 150)).sum())
    assert (tracks.valid[-1] & left).sum() >= 0.3 * n_left0
    # the last track of a reused column that is alive at the end: frame-1 row = where it was born
    # minus the crown's displacement then
    alive = reused[tracks.valid[-1, reused]]
    span = tracks.last_span()
    b = np.argmax(span[:, alive], axis=0)
    err = np.linalg.norm(tracks.points[0, alive] - (tracks.points[b, alive] - offsets[b]), axis=1)
    assert len(alive) >= 5 and np.median(err) < 0.3
    # and no step joins two tracks: a reused column is invalid in the frame before each birth
    k, c = np.nonzero(born[1:, n0:])
    assert not tracks.valid[k, c + n0].any()


def test_confidence_is_one_minus_exp_of_half_the_weights_followed():
    F = 4
    pts = np.zeros((F, 2, 2))
    pts[:, 1] = [3.0, 0.0]
    valid = np.ones((F, 2), bool)
    valid[2:, 1] = False
    s = 2.0
    m = nm.follow_tracks(np.array([[0.0, 0.0]]), _hand_tracks(pts, valid), scale=s, k_nearest=0)
    # frames 1: both tracks (weights 1 and exp(-9/8)); frames 2-3: only track 0 (weight 1)
    n1 = 1.0 + np.exp(-9.0 / (2 * s * s))
    assert m.confidence[0, 0] == 1.0
    assert m.confidence[1, 0] == pytest.approx(1 - np.exp(-n1 / 2), rel=1e-5)
    assert m.confidence[3, 0] == pytest.approx(1 - np.exp(-0.5), rel=1e-5)


def test_a_node_in_sparse_corners_widens_its_scale_to_its_fifth_nearest_track():
    """node_motion's docstring: the scale is the tree's, or the distance to the 5th nearest track of
    frame 1 where corners are sparser, at most 4 × the tree's."""
    pts = np.array([[0, 0], [1, 0], [0, 1], [1, 1], [-1, 0], [1, -1],         # dense, around node 0
                    [20, 3], [20, -4], [25, 0], [26, 0], [30, 0]], float)     # sparse, node 1 at (20, 0)
    s = nm.node_scales(np.array([[0.0, 0.0], [23.0, 0.0], [100.0, 0.0]]), pts, scale=2.0)
    assert s[0] == pytest.approx(2.0)        # 5th nearest at 1.41 px: the tree's scale
    assert s[1] == pytest.approx(7.0)        # 2, 3, 4.24, 5, then (30, 0) at 7 px
    assert s[2] == pytest.approx(8.0)        # nothing near: 4 × the tree's
    assert nm.node_scales(np.array([[23.0, 0.0]]), pts, scale=2.0, k=0)[0] == pytest.approx(2.0)


def test_a_node_whose_tracks_all_die_follows_the_crown_and_says_it_is_unsure():
    F = 6
    pts = np.zeros((F, 2, 2))
    pts[:, 0] = np.stack([np.arange(F) * 0.5, np.zeros(F)], 1)
    pts[:, 1] = [100.0, 0.0]
    valid = np.ones((F, 2), bool)
    valid[3:, 1] = False                  # the far node's only track dies at frame 3
    m = nm.follow_tracks(np.array([[0.0, 0.0], [100.0, 0.0]]), _hand_tracks(pts, valid), scale=2.0)
    # from frame 3 on node 1 moves with the crown's median step (+0.5 px a frame), confidence 0
    assert m.nodes[-1, 1, 0] == pytest.approx(100.0 + 0.5 * (F - 3), abs=1e-5)
    assert (m.confidence[3:, 1] == 0).all() and (m.confidence[1:3, 1] > 0.3).all()


def test_the_3d_solve_weights_each_node_track_term_by_its_confidence():
    # exp(-c |Kx - x'|^2 / 2 sigma^2): confidence c on a node's track term is sigma / sqrt(c) for that node
    from tree_from_video.core.reconstruct.motion import MotionParams, solve_motion
    rest = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 100.0]])
    parents, level = np.array([-1, 0]), np.zeros(2, int)
    F = 6
    targets = np.repeat(rest[None, :, [0, 2]], F, axis=0)
    targets[1:, 1, 0] = 8.0                      # the tip's tracks say: 8 px to the right
    conf = np.full((F, 2), 0.25)
    weighted = solve_motion(rest, parents, level, targets, confidence=conf)
    wide = solve_motion(rest, parents, level, targets, MotionParams(sigma_track=0.0075 / np.sqrt(0.25)))
    sure = solve_motion(rest, parents, level, targets)
    assert np.allclose(weighted.nodes, wide.nodes, atol=1e-4)
    assert 0.0 < weighted.nodes[1, 1, 0] < sure.nodes[1, 1, 0]   # a less sure node is pulled less at first


def test_overlay_colours_each_node_by_its_confidence():
    from tree_from_video.core.reconstruct import overlay
    from tree_from_video.core.reconstruct.skeleton2d import Skeleton2D
    F = 2
    nodes = np.array([[[50.0, 90.0], [50.0, 50.0], [20.0, 20.0], [80.0, 20.0]]] * F, np.float32)
    conf = np.array([[1, 1, 1, 1], [1.0, 0.6, 0.2, 0.95]], np.float32)
    sk = Skeleton2D(np.array([-1, 0, 1, 1]), nodes, np.array([0, 0, 1, 1]), 24.0, confidence=conf)
    tracks = _hand_tracks(np.zeros((F, 1, 2)), np.ones((F, 1), bool))
    tracks.camera[:] = np.eye(2, 3)
    img = overlay.draw_frame(np.zeros((100, 100, 3), np.uint8), sk, tracks, 1)
    at = [tuple(int(v) for v in img[int(y), int(x)]) for x, y in nodes[1]]
    assert at[2] == overlay.CONFIDENCE_COLOURS[0]        # 0.2: red
    assert at[1] == overlay.CONFIDENCE_COLOURS[1]        # 0.6: yellow
    assert at[3] == overlay.CONFIDENCE_COLOURS[2]        # 0.95: green


def test_the_median_of_no_neighbours_is_nan_not_an_index_error():
    """nan_median_rows over K = 0 neighbours (a refill when no track is alive: the WavingTrees clip
    at 4 fps, issue 31, ended in IndexError there) is NaN; over K > 0 it is np.nanmedian's."""
    assert np.isnan(trk.nan_median_rows(np.zeros((3, 0, 2)))).all()
    assert trk.nan_median_rows(np.zeros((3, 0, 2))).shape == (3, 2)
    a = np.array([[[1.0, 5.0], [np.nan, 7.0], [3.0, np.nan]], [[np.nan, np.nan], [np.nan, np.nan], [2.0, 4.0]]])
    np.testing.assert_allclose(trk.nan_median_rows(a), [[2.0, 6.0], [2.0, 4.0]])

