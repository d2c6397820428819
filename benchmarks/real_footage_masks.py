"""Makes the crown masks of the real clips (``benchmarks/real_footage/<key>_mask.png``: white where
frame 1 shows the tree) by the sky test clips.json's ``mask`` entry states, and a picture of each
drawn on its frame (``<key>_mask_check.png`` in ``--check``) to check it by eye.

The rule: inside the mask polygon (``mask.polygon``, default the outline) and above ``mask.ground``
(a row, default the frame's bottom), a pixel is the tree unless it is sky: HSV value ≥
``sky_value`` and saturation ≤ ``sky_sat`` (a white or grey sky), or hue within ``sky_hue`` (OpenCV
0–180) with saturation ≥ ``sky_hue_sat`` (default 40) and value ≥ ``sky_hue_value`` (default 0):
a blue sky. A 3×3 opening drops single-pixel specks.

    .venv/bin/python benchmarks/real_footage_masks.py --clips DIR [--check DIR]
"""
from __future__ import annotations

import argparse
import os
import sys

import cv2
import numpy as np
from real_clips import HERE, catalogue, prepare


def first_frame(path: str) -> np.ndarray:
    """Frame 1 of a video, BGR uint8."""
    cap = cv2.VideoCapture(path)
    ok, frame = cap.read()
    cap.release()
    if not ok:
        raise SystemExit(f"error: cannot read {path}")
    return frame


def crown_mask(frame: np.ndarray, outline: np.ndarray, rule: dict) -> np.ndarray:
    """``(h, w)`` bool: the tree's pixels of ``frame`` by ``rule`` (see the module docstring)."""
    h, w = frame.shape[:2]
    hsv = cv2.cvtColor(frame, cv2.COLOR_BGR2HSV).astype(int)
    hue, sat, val = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    sky = (val >= rule.get("sky_value", 256)) & (sat <= rule.get("sky_sat", -1))
    if "sky_hue" in rule:
        lo, hi = rule["sky_hue"]
        sky |= ((hue >= lo) & (hue <= hi) & (sat >= rule.get("sky_hue_sat", 40))
                & (val >= rule.get("sky_hue_value", 0)))
    inside = np.zeros((h, w), np.uint8)
    poly = np.asarray(rule.get("polygon", outline), np.int32)
    cv2.fillPoly(inside, [poly], 1)
    inside[int(rule.get("ground", h)):] = 0
    tree = (inside > 0) & ~sky
    tree = cv2.morphologyEx(tree.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)) > 0
    return tree


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", required=True)
    ap.add_argument("--check", default="", help="folder for the pictures to check by eye")
    args = ap.parse_args()
    cat = catalogue()
    for clip in prepare(args.clips):
        rule = cat[clip.key].get("mask")
        if rule is None:
            continue
        frame = first_frame(clip.video)
        tree = crown_mask(frame, clip.outline, rule)
        cv2.imwrite(os.path.join(HERE, clip.key + "_mask.png"), tree.astype(np.uint8) * 255)
        print(f"{clip.key}: {tree.mean():.1%} of the frame")
        if args.check:
            show = frame.copy()
            show[tree] = (0.5 * show[tree] + [0, 0, 127]).astype(np.uint8)
            edge = cv2.morphologyEx(tree.astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
            show[edge] = (0, 255, 255)
            cv2.imwrite(os.path.join(args.check, clip.key + "_mask_check.png"), np.hstack([frame, show]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
