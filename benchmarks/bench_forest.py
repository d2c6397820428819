"""Forest benchmark (issue: 100 trees of ~200 bones × 250 frames built in ≤ 60 s): the Generate
Forest operator end to end (growing in the core + building in Blender), bare and with leaves,
printed with the ratio to the target. Every tree grown and built on its own (*Variants* 0, the
hard case; ``--variants V`` builds V variants and instances them, as the panel's default does).

    .venv/bin/python benchmarks/bench_forest.py [--trees 100] [--variants 0]
"""
import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _package import load_package  # noqa: E402

TARGET_S = 60.0


def run(n: int, leaf_density: float, variants: int = 0) -> tuple[float, int, int]:
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    p = bpy.context.scene.tree_video
    p.gen_nodes, p.gen_frames, p.gen_leaf_density = 201, 250, leaf_density
    p.forest_count, p.forest_spacing, p.forest_width, p.forest_depth = n, 5.0, 120.0, 120.0
    p.forest_variants = variants
    t = time.perf_counter()
    assert bpy.ops.tree_video.generate_forest() == {"FINISHED"}
    elapsed = time.perf_counter() - t
    rigs = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    branch = sum(sum(b.name.startswith("B") for b in r.data.bones) for r in rigs)
    leaf = sum(sum(b.name.startswith("L") for b in r.data.bones) for r in rigs)
    return elapsed, branch, leaf


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trees", type=int, default=100)
    ap.add_argument("--variants", type=int, default=0)
    args = ap.parse_args()
    pkg = load_package()
    pkg.register()
    for density, label in ((0.0, "bare"), (0.25, "leaf density 0.25"), (1.0, "leaf density 1")):
        elapsed, branch, leaf = run(args.trees, density, args.variants)
        print(f"forest of {args.trees} trees, {label}: {branch / args.trees:.0f} branch bones + "
              f"{leaf / args.trees:.0f} leaf bones per tree × 250 frames in {elapsed:.1f} s "
              f"= {elapsed / TARGET_S:.2f}× the 60 s target")


if __name__ == "__main__":
    main()
