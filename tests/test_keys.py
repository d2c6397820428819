"""Keys only where the motion needs them (core/keys.py, issue 32): the reduced curves, posed by an
independent forward kinematics at every frame, stay within the stated tolerance of the full
motion, on hand cases and on reconstructed and generated trees."""
from __future__ import annotations

import numpy as np
import pytest

from tree_from_video.core import bones, keys
from tree_from_video.core.rotations import quat_mul


@pytest.fixture(scope="module")
def broad_tree_3d():
    """The committed broad sample reconstructed (90 frames, the product's look: twigs and leaves)."""
    import os

    from tree_from_video.core import pipeline
    from tree_from_video.core.pipeline import Settings

    from trees import ROOT
    folder = os.path.join(ROOT, "sample_videos", "broad")
    s = Settings(frames="0:90")
    res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
    return pipeline.build_3d(res, s, name="Solved")


@pytest.fixture(scope="module")
def generated_tree():
    from tree_from_video import api
    return api.generate("broad", n_frames=120, seed=3)[0]


def _axis_angle(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    angle = np.asarray(angle, float)
    return np.concatenate([np.cos(angle / 2)[..., None], np.sin(angle / 2)[..., None] * axis], axis=-1)


def _lerp_between(qa, qb, n):
    """``n`` normalized linear interpolations from ``qa`` to ``qb`` (both ends included)."""
    w = np.linspace(0, 1, n)[:, None]
    q = (1 - w) * qa + w * qb
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_a_curve_that_is_already_linear_keeps_its_ends_only():
    q = _lerp_between(_axis_angle([0, 0, 1], 0.0), _axis_angle([1, 1, 0], 0.6), 33)[:, None]   # (F, 1, 4)
    keep = keys.reduce_keys(q, 1e-9, smooth=False)
    assert keep[:, 0].tolist() == [True] + [False] * 31 + [True]


def test_a_corner_is_kept_and_nothing_else_is_needed():
    """Two linear pieces meeting at frame 16 (a dyadic point): the corner and the ends are kept;
    the interpolation through them is the curve itself."""
    a, b, c = _axis_angle([0, 0, 1], 0.0), _axis_angle([0, 0, 1], 0.5), _axis_angle([1, 0, 0], 0.4)
    q = np.concatenate([_lerp_between(a, b, 17), _lerp_between(b, c, 17)[1:]])[:, None]
    keep = keys.reduce_keys(q, 1e-6, smooth=False)
    assert np.flatnonzero(keep[:, 0]).tolist() == [0, 16, 32]
    np.testing.assert_allclose(keys.interpolate(q, keep, smooth=False), q, atol=1e-9)


def test_interpolation_error_is_the_angle_to_the_normalized_lerp():
    """A turn at constant speed about one axis, 0 → θ over 4 frames, keyed at its ends: the
    normalized lerp at fraction w turns by φ(w) = 2 atan2(w sin(θ/2), 1 − w + w cos(θ/2)) where the
    truth turns by wθ; exact at w = ½ by symmetry, worst at ¼ and ¾ (the equation, by hand)."""
    theta = 1.2
    q = _axis_angle([0, 1, 0], theta * np.linspace(0, 1, 5))[:, None]    # (5, 1, 4)
    err = keys.interpolation_error(q, np.arange(5.0), np.array([0]), np.array([4]))   # linear

    def phi(w):
        return 2 * np.arctan2(w * np.sin(theta / 2), 1 - w + w * np.cos(theta / 2))
    by_hand = abs(0.25 * theta - phi(0.25))
    assert phi(0.5) == pytest.approx(0.5 * theta, abs=1e-12)
    assert abs(0.75 * theta - phi(0.75)) == pytest.approx(by_hand, rel=1e-9)
    assert err[0, 0] == pytest.approx(by_hand, rel=1e-9) and by_hand > 0.005


def test_hermite_is_the_cubic_with_the_given_end_slopes():
    """h00 qa + h10 Δ ma + h01 qb + h11 Δ mb with qa = 0, qb = 1, ma = 0, mb = 3 over Δ = 1 is t³
    (the cubic with those values and slopes), and over Δ = 2 frames with slopes per frame, (t/2)³·…
    scaled: the equation, by hand."""
    u = np.linspace(0, 1, 11)
    np.testing.assert_allclose(keys.hermite(0.0, 1.0, 0.0, 3.0, 1.0, u), u ** 3, atol=1e-12)
    t = 2 * u                                                  # p(t) = t³ on [0, 2]: p' = 3t²
    np.testing.assert_allclose(keys.hermite(0.0, 8.0, 0.0, 12.0, 2.0, u), t ** 3, atol=1e-12)


def test_slopes_are_central_differences():
    q = (np.arange(6.0) ** 2)[:, None, None] * np.ones((1, 1, 4))
    m = keys.slopes(q)
    np.testing.assert_allclose(m[1:-1, 0, 0], 2 * np.arange(1.0, 5.0))      # d(t²)/dt, exact
    assert m[0, 0, 0] == 1.0 and m[-1, 0, 0] == 9.0                         # one-sided ends


@pytest.mark.parametrize("smooth", [False, True])
def test_every_span_stays_within_its_tolerance(smooth):
    rng = np.random.default_rng(4)
    F, B = 97, 6
    ang = np.cumsum(rng.normal(0, 0.02, (F, B)), axis=0) + 0.3 * np.sin(np.arange(F)[:, None] / 7.0)
    q = _axis_angle([0.3, 0.2, 1.0], ang)                                # (F, B, 4)
    tol = np.array([0.001, 0.003, 0.01, 0.03, 0.1, 0.3])
    keep = keys.reduce_keys(q, tol, smooth=smooth)
    approx = keys.interpolate(q, keep, smooth=smooth)
    err = 2 * np.arccos(np.clip(np.abs((approx * q).sum(-1)), 0, 1)).max(axis=0)
    assert np.all(err <= tol + 1e-9)
    counts = keep.sum(0)
    assert np.all(np.diff(counts) <= 0) and counts[0] > 3 * counts[-1]     # looser → fewer keys


def test_uneven_key_times_are_interpolated_in_time():
    times = np.array([0.0, 1.0, 4.0, 5.0])
    q = np.stack([_axis_angle([0, 0, 1], 0.1 * t) for t in times])[:, None]
    keep = np.array([[True], [False], [False], [True]])
    got = keys.interpolate(q, keep, times, smooth=False)
    w = 4.0 / 5.0
    want = (1 - w) * q[0, 0] + w * q[3, 0]
    np.testing.assert_allclose(got[2, 0], want / np.linalg.norm(want), atol=1e-12)


def _pose_error(tree, keep, rest_m, local):
    """The largest node error of the kept keys, interpolated here independently of core/keys.py:
    scipy's cubic Hermite through each bone's kept frames with central-difference slopes (every
    frame kept: the samples themselves), normalized, posed by forward kinematics."""
    from scipy.interpolate import CubicHermiteSpline
    rest = tree.nodes3d[0].astype(np.float64)
    full = bones.pose_tails(tree.parents, rest, rest_m, local)
    F, B = keep.shape
    t = np.arange(F, dtype=float)
    slope = np.gradient(local, axis=0)                 # central differences, one-sided at the ends
    approx = np.empty_like(local)
    for b in range(B):
        k = np.flatnonzero(keep[:, b])
        approx[:, b] = CubicHermiteSpline(t[k], local[k, b], slope[k, b])(t)
    approx /= np.linalg.norm(approx, axis=-1, keepdims=True)
    return np.linalg.norm(bones.pose_tails(tree.parents, rest, rest_m, approx) - full, axis=-1).max()


@pytest.mark.parametrize("which", ["solved", "generated"])
def test_tree_keys_hold_the_tolerance_at_every_frame(which, broad_tree_3d, generated_tree):
    """The broad sample's solved motion (noisy: every frame differs) and a generated tree's sway
    (smooth): no node strays more than KEY_TOLERANCE × H at any frame, checked by FK; the leaf
    clusters' cards within the same distance; and the reduction keeps fewer keys on smooth motion."""
    tree = broad_tree_3d if which == "solved" else generated_tree
    rest_m = bones.rest_frames(tree.parents, tree.nodes3d[0])
    local = bones.local_rotations(tree.parents, tree.nodes3d, rest_m)
    kept = keys.tree_keys(tree, rest_m)
    H = float(np.ptp(tree.nodes3d[0][:, 2]))
    assert kept.tolerance == pytest.approx(keys.KEY_TOLERANCE * H)
    err = _pose_error(tree, kept.bones, rest_m, local)
    assert err <= kept.tolerance * (1 + 1e-9)
    assert err <= kept.error * (1 + 1e-6) + 1e-12 <= kept.tolerance * (1 + 1e-6)   # error: also the leaf centres
    assert kept.bones[0].all() and kept.bones[-1].all()
    lv = tree.leaves
    assert lv is not None and lv.count > 0 and kept.leaves is None
    cyc = kept.cycle
    # the flutter as one cycle: its period from the flutter's frequency, closed, and the steady
    # sine that fits the stored flutter best (least squares, by hand here)
    hz = lv.flutter_hz
    assert hz > 0 and cyc.period == pytest.approx(tree.fps / hz)
    np.testing.assert_allclose(cyc.angles[-1], cyc.angles[0], atol=1e-12)
    t = np.arange(tree.n_frames) / tree.fps
    X = np.stack([np.sin(2 * np.pi * hz * t), np.cos(2 * np.pi * hz * t)], 1)
    fit = X @ np.linalg.lstsq(X, lv.flutter.astype(float), rcond=None)[0]
    k = np.arange(int(cyc.period) + 1)
    np.testing.assert_allclose(cyc.played[k], fit[k], atol=1e-9)
    explained = 1 - ((lv.flutter - fit) ** 2).sum() / (lv.flutter.astype(float) ** 2).sum()
    print(f"\n{which}: the steady flutter explains {explained:.0%} of the stored flutter's power")
    share = kept.share
    print(f"\n{which}: {tree.n_frames} frames x {len(kept.bones[0])} bones: kept {share:.0%} of the keys, "
          f"largest node error {err / H:.3%} of H")
    assert share < (0.75 if which == "solved" else 0.35)


def test_quat_mul_is_what_the_hand_case_assumes():
    """The hand cases build turns about one axis: composing two of them adds the angles."""
    q = quat_mul(_axis_angle([0, 0, 1], 0.2), _axis_angle([0, 0, 1], 0.3))
    np.testing.assert_allclose(q, _axis_angle([0, 0, 1], 0.5), atol=1e-12)


def test_a_clip_too_short_for_a_cycle_keys_the_flutter_linearly_within_the_tolerance():
    """Under two flutter periods there is no cycle: each cluster keeps the frames that hold its
    cards within the tolerance when keyed LINEAR, as the leaf bones are — checked here by linear
    interpolation of the quaternion channels through the kept frames, normalized."""
    from tree_from_video import api
    tree = api.generate("broad", n_frames=20, seed=5)[0]
    lv = tree.leaves
    assert lv is not None and tree.fps / lv.flutter_hz * 2 + 1 > tree.n_frames
    kept = keys.tree_keys(tree, bones.rest_frames(tree.parents, tree.nodes3d[0]))
    assert kept.cycle is None and kept.leaves is not None
    q = keys.flutter_quaternions(lv.flutter)
    t = np.arange(tree.n_frames, dtype=float)
    worst = 0.0
    for s in range(lv.count):
        k = np.flatnonzero(kept.leaves[:, s])
        qi = np.stack([np.interp(t, k, q[k, s, c]) for c in range(4)], axis=1)
        qi /= np.linalg.norm(qi, axis=1, keepdims=True)
        worst = max(worst, float(keys.rotation_angle(qi, q[:, s]).max()))
    assert worst * (lv.radius + lv.leaf_size) <= kept.tolerance * (1 + 1e-9)
    assert kept.leaves.mean() < 1.0
