"""Time from the frames' timestamps, not the header's fps (issue 18): hand cases of ``frame_times`` and a
reconstruction of the variable-frame-rate sample whose header lies, whose skeleton carries the true times."""
import os
import shutil

import numpy as np
import pytest

from tree_from_video.core.reconstruct import skeleton_io
from tree_from_video.core.reconstruct.video import frame_times

from samples import generate, load_truth, plain_settings, video_path


@pytest.mark.blender
@pytest.mark.bpy53
def test_regular_stamps_that_agree_with_the_header_change_nothing():
    t, fps, note = frame_times(np.arange(10) / 24.0 + 3.0, 24.0)
    assert np.allclose(t, np.arange(10) / 24.0) and fps == pytest.approx(24.0) and note is None


@pytest.mark.blender
@pytest.mark.bpy53
def test_a_header_that_lies_is_overruled_with_a_warning_naming_both_rates():
    # declares 15 fps; 69 frames over 30 s
    stamps = np.linspace(0, 30, 69)
    t, fps, note = frame_times(stamps, 15.0)
    assert fps == pytest.approx(68 / 30) and t[-1] == pytest.approx(30)
    assert "15 fps" in note and "2.27 fps" in note and "varies" not in note


@pytest.mark.blender
@pytest.mark.bpy53
def test_irregular_stamps_are_kept_and_unusable_ones_fall_back_to_the_header():
    stamps = np.cumsum([0, 0.04, 0.04, 0.2, 0.04, 0.1, 0.04])
    t, fps, note = frame_times(stamps, 1 / 0.04)
    assert np.allclose(t, stamps) and "varies" in note
    for bad in (np.zeros(5), np.array([0, 0.1, 0.1, 0.2, 0.3]), np.array([0, np.nan, 0.2, 0.3, 0.4])):
        t, fps, note = frame_times(bad, 12.0)
        assert np.allclose(t, np.arange(5) / 12.0) and fps == 12.0 and note is None


def test_vfr_sample_reconstruction_carries_the_frames_true_times(tmp_path):
    assert shutil.which("ffmpeg"), "install ffmpeg (Debian: apt-get install -y ffmpeg)"
    from tree_from_video.core import pipeline
    folder = generate("vfr", str(tmp_path / "vfr"))
    truth = load_truth(folder)
    res = pipeline.run(video_path(folder), os.path.join(folder, "outline.json"), plain_settings())
    sk = res.skeleton
    assert sk.nodes2d.shape[0] == len(truth["times"])            # one row per decoded frame
    assert np.abs(sk.times - (truth["times"] - truth["times"][0])).max() <= 0.0015
    assert sk.fps == pytest.approx(float(truth["fps"]), rel=0.01)
    assert abs(res.info.fps - sk.fps) >= 10                        # the header said otherwise
    assert any("header says" in w for w in res.warnings)
    path = str(tmp_path / "skeleton.npz")
    skeleton_io.save_skeleton(path, sk)
    back, _ = skeleton_io.load_skeleton(path)
    assert np.array_equal(back.times, sk.times) and np.array_equal(back.confidence, sk.confidence)


@pytest.mark.blender
@pytest.mark.bpy53
def test_uneven_times_are_kept_and_become_the_key_frames(tmp_path):
    from tree_from_video.core.tree3d import key_frames, load_tree, save_tree, uneven_times

    from trees import binary_tree
    fps = 12.0
    assert uneven_times(np.arange(8) / fps + 2.0, fps) is None              # even: keys at whole frames
    assert uneven_times(None, fps) is None
    times = np.cumsum([0, 1, 1, 3, 1, 1, 0.5, 0.5]) / fps                   # a gap and a burst
    assert np.array_equal(uneven_times(times, fps), times)
    tree = binary_tree(7, frames=8, fps=fps)
    assert np.array_equal(key_frames(tree), np.arange(1, 9))
    tree.times = times
    assert np.allclose(key_frames(tree), 1 + times * fps)                  # 1, 2, 3, 6, 7, 8, 8.5, 9
    path = str(tmp_path / "t.npz")
    save_tree(path, tree)
    assert np.array_equal(load_tree(path).times, times)


@pytest.mark.blender
@pytest.mark.bpy53
def test_a_variable_frame_rate_tree_is_keyed_at_its_frames_times(tmp_path):
    import bpy

    from tree_from_video.core.tree3d import key_frames
    from tree_from_video.operators.scene import action_api, build

    from trees import binary_tree, empty_scene  # noqa: F401
    bpy.ops.wm.read_factory_settings(use_empty=True)
    tree = binary_tree(7, frames=8, fps=12.0)
    tree.times = np.cumsum([0, 1, 1, 3, 1, 1, 0.5, 0.5]) / 12.0
    res = build.build_tree(bpy.context, tree, "VFR")
    fc = next(iter(action_api.action_fcurves(res["action"])))
    co = np.empty(2 * len(fc.keyframe_points), np.float32)
    fc.keyframe_points.foreach_get("co", co)
    assert np.allclose(co[0::2], key_frames(tree)) and co[0] == 1.0 and co[-2] == pytest.approx(9.0)
    assert bpy.context.scene.frame_end >= 9
