"""Leaf build speed: a tree with ~100K leaf polygons (issue: must build in ≤ 10 s), printed as
seconds and as a ratio to the target. Uses the committed broad sample (180 frames)."""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _package import load_package  # noqa: E402

pkg = load_package()
import bpy  # noqa: E402

from tree_from_video.core import pipeline  # noqa: E402
from tree_from_video.core.detail.twigs import TwigParams  # noqa: E402
from tree_from_video.operators.scene import build  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET_S = 10.0


def main():
    folder = os.path.join(ROOT, "sample_videos", "broad")
    s = pipeline.Settings(twigs=TwigParams(depth=2), curliness=0.0, bark="none")   # as measured before
    s.leaves.cards = 1
    res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
    tree = pipeline.build_3d(res, s)
    s.leaves.cards = max(1, round(100_000 / tree.leaves.count))
    t = time.perf_counter()
    tree = pipeline.build_3d(res, s)
    t_core = time.perf_counter() - t
    bpy.ops.wm.read_factory_settings(use_empty=True)
    t = time.perf_counter()
    built = build.build_tree(bpy.context, tree, "Bench")
    t_build = time.perf_counter() - t
    bones = len(built["armature"].data.bones)
    print(f"leaves: {tree.leaves.count} clusters × {tree.leaves.cards} cards = {built['leaf_polygons']:,} leaf polygons, "
          f"{bones} bones × {tree.n_frames} frames")
    print(f"core (lift+motion+twigs+leaves) {t_core:.2f} s; Blender build {t_build:.2f} s "
          f"(leaves {built['timings']['leaves']:.2f} s, keys {built['timings']['keys']:.2f} s) "
          f"= {t_build / TARGET_S:.2f}× the 10 s target")


if __name__ == "__main__":
    main()
