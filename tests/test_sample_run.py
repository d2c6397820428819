"""The main job on the committed sample: skeleton against its ground truth, file round trip.

Runs under the bpy wheel's Python and inside a real Blender (tests/blender/run_in_blender.py).
"""
import json
import os

import numpy as np
import pytest

from tree_from_video.core import pipeline
from tree_from_video.core.reconstruct import skeleton_io

from groundtruth import score
from samples import committed, load_truth, plain_settings

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]


@pytest.fixture(scope="module")
def broad():
    folder = committed("broad")
    res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"))
    return res, load_truth(folder)


def test_committed_sample_meets_the_bar(broad):
    res, truth = broad
    s = score(res.skeleton.parents, res.skeleton.nodes2d, truth)
    print(f"committed broad: {s}")
    assert s.chamfer1 <= 0.025 and s.chamfer_all <= 0.025 and s.coverage >= 0.75, s
    assert s.tip_corr >= 0.85 and s.freq_err <= 0.1, s


def test_mask_outline_gives_the_same_tree(broad):
    res, truth = broad
    folder = committed("broad")
    res_mask = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "mask.png"))
    s = score(res_mask.skeleton.parents, res_mask.skeleton.nodes2d, truth)
    assert s.chamfer1 <= 0.025 and s.coverage >= 0.75, s


def test_skeleton_file_round_trip(broad, tmp_path):
    res, _ = broad
    path = tmp_path / "skeleton.npz"
    skeleton_io.save_skeleton(path, res.skeleton, {"video": "x.mp4"})
    with np.load(path, allow_pickle=False) as z:
        assert set(z.files) >= {"parents", "nodes2d", "level", "fps", "meta_json"}
        assert json.loads(str(z["meta_json"]))["video"] == "x.mp4"
    back, meta = skeleton_io.load_skeleton(path)
    assert np.array_equal(back.parents, res.skeleton.parents)
    assert np.array_equal(back.nodes2d, res.skeleton.nodes2d)
    assert np.array_equal(back.level, res.skeleton.level)
    assert back.fps == pytest.approx(res.skeleton.fps) and back.kind == "traced"
    assert [p.name for p in tmp_path.iterdir()] == ["skeleton.npz"]   # no temp file left


def test_progress_reaches_the_end_and_cancel_stops(broad):
    from tree_from_video.core.errors import Cancelled
    folder = committed("broad")
    seen = []
    pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"),
                 plain_settings(frames="0:30"), lambda stage, f: seen.append((stage, f)))
    assert seen[-1][1] == pytest.approx(1.0)
    assert {"tracking", "hierarchy", "skeleton"} <= {s for s, _ in seen}
    fractions = [f for _, f in seen]
    assert fractions == sorted(fractions)

    def cancel_in_tracking(stage, f):
        return stage != "tracking"
    with pytest.raises(Cancelled):
        pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"),
                     plain_settings(frames="0:30"), cancel_in_tracking)


def test_cache_skips_tracking_and_gives_the_same_skeleton(tmp_path):
    import time
    folder = committed("broad")
    s = plain_settings(frames="0:60", cache_dir=str(tmp_path / "cache"))
    t0 = time.perf_counter()
    first = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
    t_first = time.perf_counter() - t0
    assert len(list((tmp_path / "cache").iterdir())) == 1
    stages = []
    t0 = time.perf_counter()
    again = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s,
                         lambda stage, f: stages.append(stage))
    t_again = time.perf_counter() - t0
    assert "tracking" not in stages and "tracking (cached)" in stages
    assert np.array_equal(first.skeleton.nodes2d, again.skeleton.nodes2d)
    print(f"first run {t_first:.2f} s, cached {t_again:.2f} s")
    # another frame range is another key; a corrupt file is ignored and rebuilt
    s2 = plain_settings(frames="0:50", cache_dir=s.cache_dir)
    pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s2)
    assert len(list((tmp_path / "cache").iterdir())) == 2
    for f in (tmp_path / "cache").iterdir():
        f.write_bytes(b"garbage")
    third = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
    assert np.array_equal(first.skeleton.nodes2d, third.skeleton.nodes2d)
