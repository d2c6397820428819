"""Benchmark: a generated 1280×720, 300-frame video — decode-only vs the stages, traced and paper.

    .venv/bin/python benchmarks/bench_skeleton.py [--width 1280 --height 720 --frames 300]

Prints seconds per stage and the ratio of the whole run to decode-only (target: ≤ 3×).
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

from _package import load_package

load_package()

from tree_from_video.core.reconstruct import skeleton2d  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--variant", default="broad")
    args = ap.parse_args()
    from tree_from_video.core import pipeline
    from tree_from_video.core.outline import load_outline
    from tree_from_video.core.reconstruct import hierarchy, trace, video
    from tree_from_video.core.reconstruct.tracks import TrackParams
    from tree_from_video.sample_videos import synth_tree

    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        cfg = synth_tree.config_for(args.variant, width=args.width, height=args.height, frames=args.frames)
        synth_tree.generate(cfg, tmp)
        print(f"generate video: {time.perf_counter() - t:.1f} s (not part of the ratio)")
        path = os.path.join(tmp, "video.mp4")
        info = video.open_video(path)
        t = time.perf_counter()
        n = sum(1 for _ in video.iter_frames(info))
        decode = time.perf_counter() - t
        outline = load_outline(os.path.join(tmp, "outline.json"), info.width, info.height)
        t = time.perf_counter()
        tracks, maps = pipeline.track_video(info, outline, 0, info.frame_count, TrackParams())
        t_track = time.perf_counter() - t
        t = time.perf_counter()
        hier = hierarchy.build_hierarchy(tracks)
        t_hier = time.perf_counter() - t
        t = time.perf_counter()
        skeleton2d.paper_skeleton(tracks, hier, outline)
        t_paper = time.perf_counter() - t
        t = time.perf_counter()
        trace.traced_skeleton(tracks, hier, outline, maps)
        t_traced = time.perf_counter() - t
    print(f"video: {info.width}x{info.height}, {n} frames, {tracks.n_tracks} tracks")
    print(f"{'stage':<22}{'seconds':>9}")
    for name, v in (("decode only", decode), ("tracking (+decode)", t_track), ("hierarchy", t_hier),
                    ("skeleton paper", t_paper), ("skeleton traced", t_traced)):
        print(f"{name:<22}{v:9.2f}")
    for kind, sk in (("traced", t_traced), ("paper", t_paper)):
        whole = t_track + t_hier + sk
        print(f"whole/decode ({kind}): {whole / decode:.2f}x  (target <= 3x)")
    print(f"hierarchy of 5,000 tracks x 300 frames: {hierarchy_5000():.2f} s")


def hierarchy_5000() -> float:
    """Seconds to build the hierarchy of 5,000 synthetic swaying tracks over 300 frames."""
    import numpy as np

    from tree_from_video.core.reconstruct import hierarchy
    from tree_from_video.core.reconstruct.tracks import Tracks
    rng = np.random.default_rng(0)
    P, F = 5000, 300
    p0 = rng.uniform(0, 600, (P, 2)).astype(np.float32)
    t = np.arange(F)[:, None]
    phase = p0[:, 0] / 100
    sway = np.stack([3 * np.sin(0.2 * t + phase), 2 * np.cos(0.15 * t + phase)], -1)
    tracks = Tracks((p0[None] + sway).astype(np.float32), np.ones((F, P), bool), np.zeros((F, 2, 3), np.float32),
                    np.zeros(P, np.float32), 24.0, 0, (640, 640))
    t0 = time.perf_counter()
    hierarchy.build_hierarchy(tracks)
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
