"""Details by hand: minimum-jerk curves, closed bark rings, leaf flutter."""
import numpy as np
import pytest

from tree_from_video.core.detail import shapes as details


def test_minimum_jerk_end_conditions_by_hand():
    s = details.minimum_jerk
    assert s(0.0) == 0.0 and s(1.0) == 1.0 and s(0.5) == pytest.approx(0.5)   # 10/8 − 15/16 + 6/32
    h = 1e-4
    for end in (0.0 + h, 1.0 - h):       # velocity 30τ²(1−τ)² and acceleration 60τ(1−τ)(1−2τ) vanish
        vel = (s(end + h) - s(end - h)) / (2 * h)
        acc = (s(end + h) - 2 * s(end) + s(end - h)) / h ** 2
        assert abs(vel) < 1e-5 and abs(acc) < 1e-2


def test_curly_branch_keeps_its_ends_and_bends_by_the_offset():
    a, b = np.zeros(3), np.array([0, 0, 10.0])
    pts = details.curly_branch(a, b, np.array([1.0, 0, 0]), n=9)
    assert pts[0] == pytest.approx(a) and pts[-1] == pytest.approx(b)
    assert pts[4, 0] == pytest.approx(1.0) and np.abs(pts[:, 0]).max() <= 1.0 + 1e-12


@pytest.mark.parametrize("kind", ["smooth", "rough"])
def test_bark_rings_close_and_stay_within_bounds(kind):
    amp, freqs, phases = details.random_bark(kind, seed=3)
    theta = np.linspace(0, 2 * np.pi, 721)
    r = details.bark_radius(theta, 0.1, amp, freqs, phases)
    assert r[0] == pytest.approx(r[-1], abs=1e-12)                          # seamless
    hi = details.BARK_PRESETS[kind][1]
    assert np.all(np.abs(r / 0.1 - 1) <= hi + 1e-12)
    with pytest.raises(ValueError):
        details.bark_radius(theta, 0.1, amp, freqs + 0.5, phases)


def test_flutter_peaks_at_omega_and_scales_with_branch_speed():
    fps, F = 24.0, 480
    t = np.arange(F) / fps
    omega = 2 * np.pi * 3.0                                              # 3 Hz
    speed = np.full(F, 2.0)
    y = details.flutter(t, speed, omega, beta=0.4, gain=0.05)
    spec = np.abs(np.fft.rfft(y))
    freqs = np.fft.rfftfreq(F, 1 / fps)
    assert freqs[np.argmax(spec)] == pytest.approx(3.0, abs=fps / F)
    y2 = details.flutter(t, 2 * speed, omega, beta=0.4, gain=0.05)
    assert np.abs(y2).max() == pytest.approx(2 * np.abs(y).max())
