"""Whole-run speed (issue 18): a 300-frame H.264 clip of a tree in wind (the ``hd`` sample variant:
leaves turning, thin branches swinging) at 720p, 1080p and 4K. For each size it prints

* decode only: a single-threaded ``cv2.VideoCapture`` read loop over the file;
* the wall time of the ``batch.py`` process with the default look and ``--npz --no-video``;
* each stage's wall time, from the batch's progress lines (a stage starts at its first line);
* the ratio whole run / decode (target ≤ 3×) and the batch process's peak RSS (target ≤ 600 MB
  at 4K).

Both timings are taken in the same run, one after the other (2 cores: never side by side). The
clips are generated once into ``--clips`` (4K takes a few minutes) and reused.

    .venv/bin/python benchmarks/bench_speed.py [--sizes 720p,1080p,4k] [--frames 300] [--clips DIR]
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import threading
import time

import cv2

from _package import ROOT, load_package

SIZES = {"720p": (1280, 720), "1080p": (1920, 1080), "4k": (3840, 2160)}
TARGET_RATIO = 3.0
TARGET_RSS_MB_4K = 600


def clip(size: str, frames: int, clips: str) -> str:
    """The folder of the ``hd`` variant at ``size`` with ``frames`` frames (generated if missing)."""
    folder = os.path.join(clips, f"hd_{size}_{frames}")
    if not os.path.exists(os.path.join(folder, "video.mp4")):
        load_package()
        from tree_from_video.sample_videos import synth_tree
        w, h = SIZES[size]
        t = time.perf_counter()
        synth_tree.generate(synth_tree.config_for("hd", width=w, height=h, frames=frames), folder)
        print(f"  generated {folder} in {time.perf_counter() - t:.0f} s (not timed)", flush=True)
    return folder


def decode_only(path: str) -> tuple[float, int]:
    """Seconds to read every frame with one ``cv2.VideoCapture`` loop, and the frame count."""
    t = time.perf_counter()
    cap = cv2.VideoCapture(path)
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    return time.perf_counter() - t, n


def batch_run(folder: str, out: str) -> tuple[float, dict[str, float], float, str]:
    """Wall seconds of the batch process, seconds per stage, peak RSS (MB) and its last line."""
    cmd = [sys.executable, os.path.join(ROOT, "batch.py"), os.path.join(folder, "video.mp4"),
           "--outline", os.path.join(folder, "outline.json"), "--out", out, "--npz", "--no-video", "--force"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    starts: dict[str, float] = {}
    lines: list[str] = []

    def read() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            lines.append(line.rstrip())
            m = re.match(r"\[([^\]]+)\]", line)
            if m:
                starts.setdefault(m.group(1), time.perf_counter() - t0)

    reader = threading.Thread(target=read)
    reader.start()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    reader.join()
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"batch.py failed ({proc.returncode}):\n" + "\n".join(lines[-20:]))
    order = sorted(starts.items(), key=lambda kv: kv[1])
    stages = {"start-up (imports, outline, first frame)": order[0][1] if order else wall}
    for (name, t), nxt in zip(order, order[1:] + [("end", wall)]):
        stages[name] = nxt[1] - t
    done = next((ln for ln in reversed(lines) if ln.startswith("done:")), lines[-1] if lines else "")
    return wall, stages, usage.ru_maxrss / 1024.0, done


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="720p,1080p,4k", help="comma list of " + ", ".join(SIZES))
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--clips", default=os.path.join(tempfile.gettempdir(), "tfv-bench-clips"))
    args = ap.parse_args()
    rows = []
    for size in args.sizes.split(","):
        print(f"== {size}", flush=True)
        folder = clip(size, args.frames, args.clips)
        path = os.path.join(folder, "video.mp4")
        decode, n = decode_only(path)
        with tempfile.TemporaryDirectory() as out:
            wall, stages, rss, done = batch_run(folder, out)
        print(f"  {done}")
        print(f"  decode only {decode:6.2f} s ({n} frames, {1000 * decode / max(n, 1):.1f} ms a frame)")
        for name, sec in stages.items():
            print(f"  {name:<42}{sec:6.2f} s")
        ratio = wall / decode
        print(f"  whole run   {wall:6.2f} s = {ratio:.2f}× decode (target ≤ {TARGET_RATIO:g}×), peak RSS {rss:.0f} MB"
              + (f" (target ≤ {TARGET_RSS_MB_4K} MB)" if size == "4k" else ""), flush=True)
        rows.append((size, n, decode, wall, ratio, rss))
    print(f"\n{'size':<7}{'frames':>7}{'decode s':>10}{'run s':>8}{'ratio':>7}{'peak RSS MB':>13}")
    for size, n, decode, wall, ratio, rss in rows:
        print(f"{size:<7}{n:7d}{decode:10.2f}{wall:8.2f}{ratio:6.2f}×{rss:13.0f}")


if __name__ == "__main__":
    main()
