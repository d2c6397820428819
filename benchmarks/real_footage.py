"""The look and motion on real footage (issue 31): every real clip of ``--clips`` (see
``real_clips.py``; the clips are never committed, their outlines and masks are, in
``benchmarks/real_footage/``) through the batch job with ``--form auto`` (and again with the form
clips.json names when auto picks another), then per run:

- ``IoU`` / ``cover``: frame 1 of the built tree rendered as the video frames it (Workbench in the
  bpy wheel, ``tests/silhouette.py``) against the crown's mask (``real_footage_masks.py``), and
  the share of the mask the render covers;
- ``motion``: the median correlation of the moving 2D skeleton with the dense-flow reference
  (``tests/motion_metrics.py``, issue 18's recipe) over the 30 nodes that move most;
- ``form`` picked, ``nodes``, ``clusters``, seconds of the batch process and ``x decode`` (the
  batch's seconds over one ``cv2.VideoCapture`` read loop of the clip); ``palm?`` whether the run
  suggested choosing Palm (``core/reconstruct/form.py`` ``palm_hint``).

With ``--pictures DIR`` each run leaves ``<key>_<form>.png``: frame 1, the render on grey, and
where render and mask agree (green), the crown it misses (red), the render outside it (blue).

    .venv/bin/python benchmarks/real_footage.py --clips DIR [--only trees,palm_below] [--pictures DIR]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import cv2
import numpy as np
from real_clips import RealClip, run_batch, select, write_outline

from _package import ROOT, load_package

sys.path.insert(0, os.path.join(ROOT, "tests"))


def decode_seconds(path: str) -> float:
    """Seconds of one ``cv2.VideoCapture`` read loop over the whole clip."""
    t = time.perf_counter()
    cap = cv2.VideoCapture(path)
    while cap.read()[0]:
        pass
    cap.release()
    return time.perf_counter() - t


def batch(clip: RealClip, form: str, out: str) -> tuple[float, list[str]]:
    """Run the batch job (with ``--npz``); seconds and its warning lines (raises on a failed run)."""
    r = run_batch(clip.video, write_outline(clip.outline, os.path.join(out, "outline.json")), out, form, "--npz")
    if r.code != 0:
        raise RuntimeError(f"{clip.key}: batch exited {r.code}: {r.last}")
    return r.seconds, r.warnings


def render(out: str, picture: str) -> tuple[np.ndarray, np.ndarray, object]:
    """Frame 1 of ``out/tree3d.npz`` rendered as the video frames it: (coverage (H, W) bool, RGBA
    image, the tree)."""
    import bpy
    from silhouette import render_silhouette

    from tree_from_video.core.tree3d import load_tree
    from tree_from_video.operators.scene import build
    bpy.ops.wm.read_factory_settings(use_empty=True)
    tree = load_tree(os.path.join(out, "tree3d.npz"))
    build.build_tree(bpy.context, tree, "Real")
    sil = render_silhouette(tree, picture)
    return sil, cv2.imread(picture, cv2.IMREAD_UNCHANGED), tree


def motion(clip: RealClip, out: str) -> float:
    """Median correlation of the 2D skeleton's nodes with the dense-flow reference."""
    from motion_metrics import flow_reference_correlation
    with np.load(os.path.join(out, "result.npz"), allow_pickle=False) as z:
        nodes2d = z["nodes2d"]
    cap = cv2.VideoCapture(clip.video)
    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    cap.release()
    mask = np.zeros((h, w), np.uint8)
    cv2.fillPoly(mask, [clip.outline.astype(np.int32)], 1)
    return flow_reference_correlation(clip.video, mask, nodes2d)["corr"]


def picture(frame_path: str, rgba: np.ndarray, sil: np.ndarray, mask: np.ndarray | None, path: str) -> None:
    """Frame 1, the render on grey, and where they agree: green both, red the mask alone (the
    crown the render misses), blue the render alone."""
    cap = cv2.VideoCapture(frame_path)
    ok, frame = cap.read()
    cap.release()
    a = rgba[..., 3:4].astype(np.float32) / 255.0
    grey = np.full_like(frame, 128)
    shown = (grey * (1 - a) + rgba[..., :3] * a).astype(np.uint8)
    agree = np.zeros_like(frame)
    if mask is not None:
        agree[mask & sil] = (0, 200, 0)
        agree[mask & ~sil] = (0, 0, 220)
        agree[~mask & sil] = (220, 0, 0)
    else:
        agree[sil] = (220, 220, 220)
    both = np.hstack([frame, shown, agree])
    s = min(1.0, 1500 / both.shape[1])
    cv2.imwrite(path, cv2.resize(both, None, fx=s, fy=s, interpolation=cv2.INTER_AREA) if s < 1 else both)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", required=True, help="folder of the real clips (see real_clips.py)")
    ap.add_argument("--only", default="", help="comma-separated clip keys")
    ap.add_argument("--pictures", default="", help="folder for frame 1 beside the render")
    args = ap.parse_args()
    load_package()
    clips = select(args.clips, args.only)
    print(f"{'clip':<12} {'kind':<8} {'asked':<9} {'form':<9} {'IoU':>5} {'cover':>5} {'motion':>6} "
          f"{'nodes':>5} {'clust':>5} {'s':>6} {'x dec':>5} {'palm?':>5}  warnings")
    with tempfile.TemporaryDirectory() as tmp:
        for clip in clips:
            dec = decode_seconds(clip.video)
            mask = cv2.imread(clip.mask, cv2.IMREAD_GRAYSCALE) > 127 if clip.mask else None
            asked = ["auto"]
            while asked:
                form = asked.pop(0)
                out = os.path.join(tmp, f"{clip.key}_{form}")
                os.makedirs(out, exist_ok=True)
                sec, warns = batch(clip, form, out)
                sil, rgba, tree = render(out, os.path.join(out, "render.png"))
                picked = tree.meta.get("form", "?")
                if form == "auto" and clip.form not in ("auto", picked):
                    asked.append(clip.form)
                iou = cover = float("nan")
                if mask is not None:
                    iou = float((sil & mask).sum() / max((sil | mask).sum(), 1))
                    cover = float((sil & mask).sum() / max(mask.sum(), 1))
                corr = motion(clip, out)
                n_cl = tree.leaves.count if tree.leaves is not None else 0
                print(f"{clip.key:<12} {clip.kind:<8} {form:<9} {picked:<9} {iou:>5.2f} {cover:>5.2f} {corr:>6.2f} "
                      f"{tree.n_nodes:>5} {n_cl:>5} {sec:>6.1f} {sec / max(dec, 1e-6):>5.1f} "
                      f"{'yes' if any('Form: Palm' in w for w in warns) else '-':>5}  {len(warns)}",
                      flush=True)
                if args.pictures:
                    os.makedirs(args.pictures, exist_ok=True)
                    picture(clip.video, rgba, sil, mask, os.path.join(args.pictures, f"{clip.key}_{form}.png"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
