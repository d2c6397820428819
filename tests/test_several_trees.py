"""Several trees in one shot (issue 31, item 4): an outline file of several polygons, or a mask of
several components, gives one tree per outline from one decode and one tracking pass; the batch
writes ``DIR/tree_<k>/``. The clip: the committed ``broad`` and ``sparse`` samples side by side
(960 × 360), each tree's ground truth moved with it."""
import json
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from tree_from_video.core import pipeline
from tree_from_video.core.errors import InputError
from tree_from_video.core.outline import load_outlines
from tree_from_video.core.reconstruct import run as run_mod

from groundtruth import score
from samples import committed, load_truth

pytestmark = [pytest.mark.bpy53]

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FRAMES = 24


@pytest.fixture(scope="module")
def two_trees(tmp_path_factory):
    """(video, outlines.json, [broad truth, sparse truth moved 480 px right]) of the side-by-side clip."""
    folder = tmp_path_factory.mktemp("two")
    caps = [cv2.VideoCapture(os.path.join(committed(n), "video.mp4")) for n in ("broad", "sparse")]
    video = str(folder / "two.mp4")
    out = cv2.VideoWriter(video, cv2.VideoWriter_fourcc(*"mp4v"), 24, (960, 360))
    for _ in range(FRAMES):
        out.write(np.hstack([c.read()[1] for c in caps]))
    out.release()
    polys = [json.load(open(os.path.join(committed(n), "outline.json")))["polygon"] for n in ("broad", "sparse")]
    polys[1] = [[x + 480, y] for x, y in polys[1]]
    path = str(folder / "outlines.json")
    json.dump(polys, open(path, "w"))
    truths = [load_truth(committed(n)) for n in ("broad", "sparse")]
    truths[1] = dict(truths[1], nodes2d=truths[1]["nodes2d"] + np.array([480.0, 0.0]))
    return video, path, truths


def test_an_outline_file_holds_one_or_several_trees(tmp_path):
    sq = [[10, 10], [60, 10], [60, 80], [10, 80]]
    right = [[x + 100, y] for x, y in sq]
    for data, n in ((sq, 1), ({"polygon": sq}, 1), ([sq, right], 2), ({"polygons": [sq, right]}, 2)):
        p = tmp_path / "o.json"
        p.write_text(json.dumps(data))
        outs = load_outlines(str(p), 200, 100)
        assert len(outs) == n
        assert outs[-1].mask[40, 30 + 100 * (n - 1)] and outs[0].mask[40, 30]
    if True:                                   # a mask: each large component a tree, left to right
        m = np.zeros((100, 200), np.uint8)
        m[10:80, 120:170] = 255
        m[10:80, 10:60] = 255
        m[5:7, 90:92] = 255                    # a speck of paint
        cv2.imwrite(str(tmp_path / "m.png"), m)
        outs = load_outlines(str(tmp_path / "m.png"), 200, 100)
        assert len(outs) == 2 and outs[0].mask[40, 30] and outs[1].mask[40, 140] and not outs[0].mask[6, 91]
        m[10:80, 120:170] = 0                  # one tree and a speck: the whole mask, as before
        cv2.imwrite(str(tmp_path / "m.png"), m)
        outs = load_outlines(str(tmp_path / "m.png"), 200, 100)
        assert len(outs) == 1 and outs[0].mask[6, 91]
    p = tmp_path / "bad.json"
    p.write_text(json.dumps([sq, [[1, 1], [2, 2]]]))
    with pytest.raises(InputError, match="polygon 2"):
        load_outlines(str(p), 200, 100)


def test_two_trees_in_one_shot_are_two_skeletons_from_one_decode(two_trees, monkeypatch):
    """Each tree's skeleton stays in its own outline and matches its own truth as closely as a
    reconstruction of it alone does (frame-1 chamfer ≤ 3 % of its height, coverage ≥ 0.8); the
    video is decoded once (plus frame 1 read again for the foreground); built as one shot, the
    trees share a scale and stand where the video shows them."""
    video, path, truths = two_trees
    decoded = [0]
    real = run_mod.iter_frames

    def counting(*a, **k):
        for f in real(*a, **k):
            decoded[0] += 1
            yield f
    monkeypatch.setattr(run_mod, "iter_frames", counting)
    results = pipeline.run_all(video, path, pipeline.Settings(frames=f"0:{FRAMES}"))
    assert len(results) == 2
    assert decoded[0] == FRAMES + 1
    outlines = load_outlines(path, 960, 360)
    for k, (res, truth) in enumerate(zip(results, truths)):
        p0 = np.round(res.skeleton.nodes2d[0]).astype(int)
        own = cv2.dilate(outlines[k].mask.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
        assert own[p0[:, 1].clip(0, 359), p0[:, 0].clip(0, 959)].all()
        other = outlines[1 - k].mask
        assert not other[p0[:, 1].clip(0, 359), p0[:, 0].clip(0, 959)].any()
        s = score(res.skeleton.parents, res.skeleton.nodes2d, truth)
        print(f"\ntree {k + 1}: chamfer {s.chamfer1:.4f} H, coverage {s.coverage:.3f}, tips {s.tip_corr:.2f}")
        assert s.chamfer1 <= 0.03 and s.coverage >= 0.8
    # one scale for the shot, each tree where it stands: the taller (broad) is height_m tall, the
    # sparse one in proportion, its base 480 px + the bases' offset to the right, on the same ground
    trees = pipeline.build_shot(results, pipeline.Settings(frames=f"0:{FRAMES}"), ["A", "B"])
    m = trees[0].meta["metres_per_px"]
    assert trees[1].meta["metres_per_px"] == m
    heights = [float(np.ptp(t.nodes3d[0, :, 2])) for t in trees]
    px = [float(np.ptp(r.skeleton.nodes2d[0, :, 1])) for r in results]
    assert heights[1] / heights[0] == pytest.approx(px[1] / px[0], rel=0.1)
    b = [np.asarray(t.meta["base_px"]) for t in trees]
    assert trees[0].meta["shot_offset_m"] == [0.0, 0.0, 0.0]
    assert trees[1].meta["shot_offset_m"][0] == pytest.approx((b[1][0] - b[0][0]) * m)
    assert trees[1].meta["shot_offset_m"][0] > 400 * m and abs(trees[1].meta["shot_offset_m"][2]) < 10 * m


def test_pipeline_run_takes_one_tree_and_says_so(two_trees):
    video, path, _ = two_trees
    with pytest.raises(InputError, match="holds 2 trees"):
        pipeline.run(video, path, pipeline.Settings(frames="0:4"))


def test_the_batch_writes_one_folder_per_tree_and_refuses_generate(two_trees, tmp_path):
    video, path, _ = two_trees
    out = tmp_path / "out"
    cmd = [sys.executable, os.path.join(ROOT, "batch.py"), video, "--outline", path, "--out", str(out),
           "--frames", "0:8", "--no-video"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr[-800:]
    for k in (1, 2):
        with np.load(out / f"tree_{k}" / "skeleton.npz", allow_pickle=False) as z:
            assert z["nodes2d"].shape[0] == 8
        assert (out / f"tree_{k}" / "tree3d.npz").exists()
    p = subprocess.run(cmd[:-1] + ["--generate", "2", "--force"], capture_output=True, text=True)
    assert p.returncode == 2 and "holds 2" in p.stderr and "Traceback" not in p.stderr


def test_a_list_of_points_is_one_polygon_and_a_list_of_polygons_several(two_trees):
    from tree_from_video.core.reconstruct.run import count_outlines
    video = two_trees[0]
    sq = [[10, 10], [200, 10], [200, 300], [10, 300]]
    assert count_outlines(video, sq) == 1
    assert count_outlines(video, np.array(sq, float)) == 1
    assert count_outlines(video, [np.array(sq, float), np.array(sq, float) + [400, 0]]) == 2
    assert count_outlines(video, two_trees[1]) == 2


def test_auto_outline_finds_two_trees_that_stand_apart(two_trees):
    """``--outline auto`` on the side-by-side clip: two outlines, left to right, each holding its
    own tree's frame-1 nodes and none of the other's (trees that stand apart are never joined)."""
    from tree_from_video.core.reconstruct.run import count_outlines, read_outlines
    from tree_from_video.core.reconstruct.video import open_video
    video, _, truths = two_trees
    assert count_outlines(video, "auto") == 2
    outs = read_outlines(open_video(video), 0, "auto", 1.0)
    for k, truth in enumerate(truths):
        p = np.round(truth["nodes2d"][0]).astype(int)
        inside = [o.mask[p[:, 1].clip(0, 359), p[:, 0].clip(0, 959)].mean() for o in outs]
        print(f"\ntree {k + 1}: share of its true nodes in outline 1, 2: {inside[0]:.2f}, {inside[1]:.2f}")
        assert inside[k] >= 0.8 and inside[1 - k] == 0.0
