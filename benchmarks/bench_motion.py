"""Benchmark: 3D motion on a 127-node skeleton × 300 frames, per frame for both solvers (target
for the probabilistic solver: ≤ 5 ms per frame on 2 cores).

    .venv/bin/python benchmarks/bench_motion.py
"""
from __future__ import annotations

import time

import numpy as np

from tree_from_video.core.reconstruct import motion

from _package import load_package


def binary_tree(levels: int = 7, frames: int = 300, seed: int = 0):
    """A 127-node binary tree in the plane frame (px) with swaying 2D targets ``(F, N, 2)``."""
    rng = np.random.default_rng(seed)
    parents, pos, level = [-1], [np.zeros(3)], [0]
    frontier = [0]
    for lv in range(1, levels):
        nxt = []
        for p in frontier:
            for side in (-1, 1):
                ang = side * rng.uniform(0.3, 0.7)
                length = 60 * 0.75 ** lv
                d = np.array([np.sin(ang), rng.uniform(-0.5, 0.5), np.cos(ang)]) * length
                parents.append(p)
                pos.append(pos[p] + d)
                level.append(lv)
                nxt.append(len(pos) - 1)
        frontier = nxt
    parents, pos, level = np.array(parents), np.array(pos), np.array(level)
    pos[:, 1] = 0.0
    t = np.arange(frames)[:, None] / 24.0
    sway = (0.5 + level[None]) * np.sin(2 * np.pi * 0.7 * t + level[None])
    targets = np.repeat(pos[None, :, [0, 2]], frames, axis=0)
    targets[..., 0] += sway
    return parents, pos, level, targets


def main() -> None:
    load_package()
    parents, pos, level, targets = binary_tree()
    rest = pos.copy()
    rest[:, 1] = np.random.default_rng(1).uniform(-20, 20, len(pos)) * (level > 1)
    F, N = targets.shape[:2]
    print(f"skeleton: {N} nodes, {F} frames")
    for solver in ("probabilistic", "deterministic"):
        t0 = time.perf_counter()
        motion.solve_motion(rest, parents, level, targets, motion.MotionParams(solver=solver))
        dt = (time.perf_counter() - t0) / (F - 1) * 1000
        print(f"motion {solver:<14}: {dt:6.2f} ms per frame" + ("  (target <= 5 ms)" if solver == "probabilistic" else ""))


if __name__ == "__main__":
    main()
