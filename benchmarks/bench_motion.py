"""Benchmark: 3D motion per frame for both solvers on a traced-like skeleton — a 6-level binary
tree whose every edge is a chain of 5 nodes (311 nodes, 30 deep; the broad sample's traced
skeleton is 185 nodes, 36 deep) × 300 frames. Target for the probabilistic solver (issue 18):
≤ 3 ms per frame for 300 nodes.

    .venv/bin/python benchmarks/bench_motion.py
"""
from __future__ import annotations

import time

import numpy as np

from _package import load_package

load_package()

from tree_from_video.core.reconstruct import motion  # noqa: E402


def binary_tree(levels: int = 7, frames: int = 300, seed: int = 0, segments: int = 1):
    """A binary tree of ``levels`` levels in the plane frame (px), each edge a chain of
    ``segments`` nodes, with swaying 2D targets ``(F, N, 2)``."""
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
                for k in range(segments):
                    parents.append(p if k == 0 else len(pos) - 1)
                    pos.append(pos[p] + d * (k + 1) / segments)
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
    parents, pos, level, targets = binary_tree(levels=6, segments=5)
    rest = pos.copy()
    rest[:, 1] = np.random.default_rng(1).uniform(-20, 20, len(pos)) * (level > 1)
    F, N = targets.shape[:2]
    print(f"skeleton: {N} nodes, {F} frames")
    for solver in ("probabilistic", "deterministic"):
        t0 = time.perf_counter()
        motion.solve_motion(rest, parents, level, targets, motion.MotionParams(solver=solver))
        dt = (time.perf_counter() - t0) / (F - 1) * 1000
        goal = f"  = {dt / 3.0:.2f}× the 3 ms target" if solver == "probabilistic" else ""
        print(f"motion {solver:<14}: {dt:6.2f} ms per frame{goal}")


if __name__ == "__main__":
    main()
