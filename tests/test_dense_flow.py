"""core/reconstruct/dense_flow.py and node_motion.fuse: the dense flow from frame 1 as the
nodes' second motion source."""
import cv2
import numpy as np
import pytest

from tree_from_video.core.reconstruct import dense_flow as df
from tree_from_video.core.reconstruct import node_motion as nm
from tree_from_video.core.reconstruct import tracks as trk


def _texture(h=200, w=240, seed=0):
    rng = np.random.default_rng(seed)
    img = cv2.GaussianBlur(rng.uniform(0, 255, (h, w)).astype(np.float32), (0, 0), 1.5)
    img = (img - img.min()) / np.ptp(img) * 255
    return img.astype(np.uint8)


def _shift(img, dx, dy):
    m = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(img, m, img.shape[::-1], flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)


def test_sample_is_bilinear_on_the_grid_and_linear_in_time():
    """Grid sample (i, j) at origin + step·(j, i); frames between two flows get the linear blend,
    frame 0 nothing, frames after the last flow its value."""
    gh, gw = 3, 4
    jj, ii = np.meshgrid(np.arange(gw), np.arange(gh))
    field = np.stack([jj * 1.0, ii * 2.0], -1)                       # disp x = j, y = 2i
    disp = np.stack([field, 3 * field]).astype(np.float16)           # frames 2 and 4
    err = np.stack([np.full((gh, gw), 0.5), np.full((gh, gw), 1.5)]).astype(np.float16)
    fl = df.AnchoredFlow(np.array([2, 4]), disp, err, origin=np.array([10.0, 20.0]), step=np.array([5.0, 5.0]))
    pts = np.array([[10.0 + 5 * 1.5, 20.0 + 5 * 0.5]])               # grid (j, i) = (1.5, 0.5)
    d, e = fl.sample(pts, 6)
    want2 = np.array([1.5, 1.0])
    assert d[0, 0] == pytest.approx([0, 0]) and e[0, 0] == 0
    assert d[1, 0] == pytest.approx(want2 / 2, abs=1e-3)              # halfway from frame 0 to 2
    assert d[2, 0] == pytest.approx(want2, abs=1e-3)
    assert d[3, 0] == pytest.approx(2 * want2, abs=1e-3)             # halfway between 1x and 3x
    assert d[5, 0] == pytest.approx(3 * want2, abs=1e-3)             # held after the last flow
    assert e[3, 0] == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("max_px", [1000.0, 100.0])
def test_a_shifted_texture_is_measured_in_frame_px_and_agrees_with_itself(max_px):
    """A frame that is frame 1 moved by (2.5, -1.5) px: the flow at the crown is that move in frame
    px whether the flow works at full size or scaled down (max_px); forward and back agree."""
    g0 = _texture()
    bbox = (60, 40, 180, 160)                                        # a 120 px tree
    acc = df.FlowAccumulator(g0, bbox, scale=1.0, hz=10.0, max_px=max_px)
    acc.add(1, acc.compute(_shift(g0, 2.5, -1.5), 0.1))
    fl = acc.result()
    d, e = fl.sample(np.array([[120.0, 100.0], [90.0, 70.0]]), 2)
    assert d[1] == pytest.approx(np.array([[2.5, -1.5]] * 2), abs=0.15)
    assert (e[1] < 0.3).all()


def test_flows_are_computed_at_most_hz_times_a_second_and_never_with_hz_0():
    g0 = _texture()
    acc = df.FlowAccumulator(g0, (60, 40, 180, 160), 1.0, hz=10.0)
    got = [acc.compute(g0, t) is not None for t in (0.04, 0.08, 0.12, 0.16, 0.2, 0.24)]
    assert got == [True, False, False, True, False, False]           # 0.04, then 0.16 (>= 0.1 s later)
    off = df.FlowAccumulator(g0, (60, 40, 180, 160), 1.0, hz=0.0)
    assert off.compute(g0, 1.0) is None and off.result() is None


def test_an_occluded_patch_disagrees_forward_and_back():
    """Where frame t shows something else (a patch of new texture), the flow cannot be inverted: its
    confidence there falls below e^-2."""
    g0 = _texture()
    g1 = _shift(g0, 1.0, 0.0)
    g1[80:130, 100:150] = _texture(50, 50, seed=9)
    acc = df.FlowAccumulator(g0, (60, 40, 180, 160), 1.0, hz=10.0)
    acc.add(1, acc.compute(g1, 0.1))
    _, e = acc.result().sample(np.array([[125.0, 105.0], [80.0, 60.0]]), 2)
    assert e[1, 0] > 2 * nm.FLOW_FB_PX and e[1, 1] < nm.FLOW_FB_PX


def _tracks_with(flow, F, camera=None):
    P = 1
    cam = np.repeat(np.array([[[1.0, 0, 0], [0, 1.0, 0]]], np.float32), F, axis=0) if camera is None else camera
    return trk.Tracks(np.zeros((F, P, 2), np.float32), np.ones((F, P), bool), cam, np.zeros(P, np.float32),
                      24.0, 0, (100, 100), flow=flow)


def test_fuse_weighs_tracks_and_flow_by_their_confidences():
    """eq. fuse by hand: c = 0.5 for the tracks, the flow disagreeing by FLOW_FB_PX (c_f = e^-1/2);
    the camera's map (image -> frame 1: a 3 px shift left) is applied to the flow's position; the
    fixed node keeps the tracks' motion."""
    F = 2
    disp = np.zeros((1, 2, 2, 2), np.float16)
    disp[0, ..., 0] = 4.0                                            # the flow: +4 px in x
    err = np.full((1, 2, 2), nm.FLOW_FB_PX, np.float16)
    fl = df.AnchoredFlow(np.array([1]), disp, err, np.array([0.0, 0.0]), np.array([100.0, 100.0]))
    cam = np.repeat(np.array([[[1.0, 0, 0], [0, 1.0, 0]]], np.float32), F, axis=0)
    cam[1, 0, 2] = -3.0
    nodes0 = np.array([[10.0, 10.0], [20.0, 10.0]])
    x_f, c_f = nm.flow_positions(nodes0, _tracks_with(fl, F, cam), fixed=np.array([False, True]))
    cf = np.exp(-0.5)
    assert x_f[1, 0] == pytest.approx([10.0 + 4.0 - 3.0, 10.0], abs=1e-4)
    assert c_f[1] == pytest.approx([cf, 0.0]) and c_f[0] == pytest.approx([0.0, 0.0])
    x, c = nm.fuse(nodes0 + [[2.0, 0.0], [2.0, 0.0]], np.array([0.5, 0.5]), x_f[1], c_f[1])
    assert x[0, 0] == pytest.approx((0.5 * 12.0 + cf * 11.0) / (0.5 + cf), abs=1e-4)
    assert c[0] == pytest.approx(1 - 0.5 * (1 - cf), abs=1e-5)
    assert x[1, 0] == pytest.approx(22.0) and c[1] == pytest.approx(0.5)
    assert nm.flow_positions(nodes0, _tracks_with(None, F)) is None


def test_a_track_born_later_is_anchored_at_the_fused_position():
    """eq. d_n(t) with eq. fuse as it goes: track A (+2 px) dies after frame 2, track B is born in
    frame 2 and moves +1 px by frame 3; the flow puts the node at +6 px, disagreeing with itself by
    FLOW_FB_PX (c_f = e^-1/2). The node's frame-3 position is B's move added to its *fused* frame-2
    displacement, fused again; anchoring B on the tracks' own +2 would leave it 1 px short."""
    F = 4
    disp = np.zeros((3, 2, 2, 2), np.float16)
    disp[..., 0] = 6.0
    fl = df.AnchoredFlow(np.array([1, 2, 3]), disp, np.full((3, 2, 2), nm.FLOW_FB_PX, np.float16),
                         np.zeros(2), np.array([100.0, 100.0]))
    pts = np.zeros((F, 2, 2), np.float32)
    pts[:, 0] = [[10, 10], [12, 10], [12, 10], [12, 10]]
    pts[:, 1] = [[12, 10], [12, 10], [12, 10], [13, 10]]
    valid = np.array([[1, 0], [1, 0], [1, 1], [0, 1]], bool)
    cam = np.repeat(np.array([[[1.0, 0, 0], [0, 1.0, 0]]], np.float32), F, axis=0)
    tr = trk.Tracks(pts, valid, cam, np.zeros(2, np.float32), 24.0, 0, (100, 100), flow=fl)
    m = nm.follow_tracks(np.array([[10.0, 10.0]]), tr, scale=2.0, k_nearest=0)
    c1, cf = 1.0 - np.exp(-0.5), np.exp(-0.5)                        # one track at distance 0; the flow
    x2 = (c1 * 12.0 + cf * 16.0) / (c1 + cf)                         # fused with the flow
    w_b = np.exp(-(x2 - 12.0) ** 2 / (2 * 2.0 ** 2))                 # B's weight: born 2.4 px away
    c3 = 1.0 - np.exp(-w_b / 2.0)
    x3 = (c3 * (x2 + 1.0) + cf * 16.0) / (c3 + cf)
    assert m.nodes[2, 0, 0] == pytest.approx(x2, abs=1e-4)
    assert m.nodes[3, 0, 0] == pytest.approx(x3, abs=1e-4)
    assert m.confidence[3, 0] == pytest.approx(1.0 - (1.0 - c3) * (1.0 - cf), abs=1e-5)
    assert m.nodes[3, 0, 0] - (c1 * 13.0 + cf * 16.0) / (c1 + cf) > 0.8


def test_a_clip_in_wind_tracks_and_flows_and_its_cache_keeps_the_flow(tmp_path):
    """The tracker's pass fills the flow at about flow_hz; the stage cache round-trips it."""
    import os

    from tree_from_video.core import pipeline
    from tree_from_video.core.reconstruct import cache

    from samples import ROOT, plain_settings

    folder = os.path.join(ROOT, "sample_videos", "broad")
    s = plain_settings(frames="0:48")
    s.cache_dir = str(tmp_path)
    res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
    fl = res.tracks.flow
    assert fl is not None
    assert fl.frames[0] == 1                                         # the first frame after frame 1
    gaps = np.diff(res.tracks.times[fl.frames])
    assert gaps.min() >= 1 / s.track.flow_hz - 1e-6 and gaps.max() < 2 / s.track.flow_hz
    key = [f for f in os.listdir(tmp_path) if f.startswith("stages-")][0][7:-4]
    back = cache.load(str(tmp_path), key)[0].flow
    assert np.array_equal(back.frames, fl.frames) and np.array_equal(back.disp, fl.disp)
    assert back.origin == pytest.approx(fl.origin) and back.step == pytest.approx(fl.step)
