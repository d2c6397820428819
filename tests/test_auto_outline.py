"""Automatic outline: what sways while the background stays still."""
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from tree_from_video.core.errors import InputError
from tree_from_video.core.reconstruct.auto_outline import auto_outline
from tree_from_video.core.reconstruct.video import open_video

from samples import ROOT, committed


def test_auto_outline_finds_the_tree():
    folder = committed("broad")
    o = auto_outline(open_video(os.path.join(folder, "video.mp4")))
    truth = cv2.imread(os.path.join(folder, "mask.png"), cv2.IMREAD_GRAYSCALE) > 0
    iou = (o.mask & truth).sum() / (o.mask | truth).sum()
    print(f"automatic outline IoU with the drawn one: {iou:.2f}")
    assert iou >= 0.7


def test_a_still_video_is_a_clear_error(tmp_path):
    frame = cv2.imread(os.path.join(committed("broad"), "mask.png"))
    frame = cv2.GaussianBlur(np.random.default_rng(0).integers(0, 255, frame.shape).astype(np.uint8), (0, 0), 2)
    path = str(tmp_path / "still.avi")
    w = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"MJPG"), 24, (frame.shape[1], frame.shape[0]))
    for _ in range(30):
        w.write(frame)
    w.release()
    with pytest.raises(InputError, match="draw the outline"):
        auto_outline(open_video(path))


def test_batch_accepts_outline_auto(tmp_path):
    p = subprocess.run([sys.executable, os.path.join(ROOT, "batch.py"), os.path.join(committed("broad"), "video.mp4"),
                        "--outline", "auto", "--out", str(tmp_path / "o"), "--frames", "0:48", "--no-video"],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "o" / "tree3d.npz").exists()
