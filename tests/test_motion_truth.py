"""benchmarks/motion_truth.py, the harness the motion of issue 18 is judged by: its measurements by
hand, and one short run end to end."""

import numpy as np
import pytest

from samples import motion_truth_harness

mt = motion_truth_harness()


def test_camera_error_is_the_centre_displacement_against_the_true_offset():
    F = 5
    cam = np.tile(np.array([[1.0, 0, 0], [0, 1.0, 0]], np.float32), (F, 1, 1))
    assert mt.camera_error(cam, np.zeros((F, 2)), (480, 360)) == 0.0
    off = np.zeros((F, 2))
    off[3] = [2.0, -1.0]                                   # the image moved by (2, -1) at frame 3
    cam[3, :, 2] = [-2.0, 1.0]                             # and the map back to frame 1 undoes it
    assert mt.camera_error(cam, off, (480, 360)) == pytest.approx(0.0, abs=1e-6)
    cam[3, :, 2] = 0.0                                     # a tracker that missed it: 2.24 px off
    assert mt.camera_error(cam, off, (480, 360)) == pytest.approx(np.hypot(2, 1), abs=1e-6)
    rot = np.tile(np.array([[1.0, 0, 0], [0, 1.0, 0]], np.float32), (F, 1, 1))
    rot[1, :, :2] = [[np.cos(0.01), -np.sin(0.01)], [np.sin(0.01), np.cos(0.01)]]   # a turn about the origin
    assert mt.camera_error(rot, np.zeros((F, 2)), (480, 360)) == pytest.approx(0.01 * np.hypot(240, 180), rel=0.01)


def test_survival_counts_live_tracks_over_those_of_frame_1():
    valid = np.ones((80, 10), bool)
    valid[10:, :5] = False
    valid[30:, 5:8] = False
    assert mt.survival(valid) == pytest.approx([0.5, 0.2, 0.2, 0.2])
    short = mt.survival(valid[:20])
    assert short[0] == 0.5 and np.isnan(short[1]) and np.isnan(short[2]) and short[3] == 0.5


def test_seeds_follow_the_documented_split():
    from tree_from_video.sample_videos import synth_tree as st
    assert mt.seeds_of("palm", "dev") == [(s, "dev") for s in st.SEEDS["palm"]["dev"]]
    assert mt.seeds_of("palm", "held_out") == [(s, "held") for s in st.SEEDS["palm"]["held_out"]]
    assert [s for s, _ in mt.seeds_of("broad", "all")] == [0, 101, 102]
    assert mt.seeds_of("broad", "0,7,101") == [(0, "dev"), (7, "other"), (101, "held")]


@pytest.mark.slow
def test_a_short_run_measures_everything(tmp_path, capsys):
    folder = mt.sample("gusts", 1, str(tmp_path))
    r = mt.measure("gusts", 1, folder, frames=48)
    assert r["frames"] == r["truth_frames"] == 48
    assert r["chamfer1"] < 0.03 and r["coverage"] > 0.8, r
    assert r["tip2d"]["n"] > 10 and -1 <= r["tip2d"]["corr"] <= 1 and r["tip3d"]["n"] == r["tip2d"]["n"]
    assert len(r["survival"]) == 4 and 0 <= r["survival"][-1] <= 1 and np.isnan(r["survival"][2])
    assert r["tripod"] and 0 <= r["camera_px"] < 5
    assert r["ref"]["n"] > 0 and -1 <= r["ref"]["corr"] <= 1 and -1 <= r["ref"]["truth_corr"] <= 1
    # gusts swing their thinnest twigs on their own: without those joints the truth bends less
    assert 0 < r["bend"]["rigid"] < r["bend"]["all"] and r["bend"]["ours"] > 0, r["bend"]
    assert 0 <= r["fit"]["max"] and 0 <= r["fit"]["unmeasured"] <= 1, r["fit"]
    r["split"] = "dev"
    line = mt.row(r)
    assert line.startswith("   1 dev") and line.count("|") == 9
    with pytest.raises(SystemExit):
        mt.main(["--variants", "nope"])
    assert "unknown variants" in capsys.readouterr().err
