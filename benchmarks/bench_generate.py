"""Benchmark: generating trees from a species model in the core (no Blender).

* one ~200-bone tree × 250 frames (target ≤ 0.5 s): median of 5 seeds, with the stages;
* the core part of a 100-tree forest (~200 bones × 250 frames each; the whole forest including
  the Blender build must stay ≤ 60 s).

    .venv/bin/python benchmarks/bench_generate.py [--trees 100] [--species broad]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from _package import load_package

load_package()

from tree_from_video.core.generate import species  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trees", type=int, default=100)
    ap.add_argument("--species", default="broad")
    args = ap.parse_args()
    from tree_from_video.core.generate import envelopes, forest, growth
    model = species.load_species(species.species_library()[args.species])
    env = envelopes.topiary("circle", 8.0)
    p = growth.GrowParams(node_budget=201, n_frames=250)
    growth.grow_tree(model, env, p)                                   # warm-up (imports, caches)

    times, stages = [], []
    for seed in range(5):
        marks = {}
        t0 = time.perf_counter()

        def progress(stage, frac, marks=marks, t0=t0):
            marks.setdefault(stage, time.perf_counter() - t0)
        tree = growth.grow_tree(model, env, growth.GrowParams(seed=seed, node_budget=201, n_frames=250), progress=progress)
        times.append(time.perf_counter() - t0)
        stages.append(marks)
    print(f"one tree: {tree.n_nodes - 1} bones × {tree.n_frames} frames: median {np.median(times):.3f} s "
          f"(min {min(times):.3f}, max {max(times):.3f}; target ≤ 0.5 s)")
    m = stages[int(np.argsort(times)[len(times) // 2])]
    order = sorted(m.items(), key=lambda kv: kv[1])
    print("  stage starts (s):", ", ".join(f"{k} {v:.3f}" for k, v in order))

    t0 = time.perf_counter()
    pos = forest.scatter_area(args.trees, 200.0, 200.0, 8.0, seed=1)
    slots = forest.forest_slots(pos, seed=1)
    t_place = time.perf_counter() - t0
    t0 = time.perf_counter()
    trees = forest.generate_forest(model, env, slots, p)
    t_forest = time.perf_counter() - t0
    bones = [t.n_nodes - 1 for t in trees]
    print(f"forest: {len(trees)} trees, {np.mean(bones):.0f} bones each × 250 frames: placement {t_place:.3f} s, "
          f"generation {t_forest:.1f} s ({t_forest / len(trees):.3f} s per tree)")


if __name__ == "__main__":
    main()
