"""The farm's throughput (issue 34): videos per hour on this machine for 720p 10 s clips (the
``hd`` wind sample at 1280×720, 240 frames at 24 fps, four seeds), run by ``batch.py --farm`` on a
local Dask cluster of 1 and then 2 worker processes (each run from empty output folders; the
default look, ``--npz --no-video``). Prints wall seconds, videos per hour, the speed-up of 2
workers over 1 and the jobs' peak RSS (from their reports). The clips are generated once into
``--clips`` and reused.

    .venv/bin/python benchmarks/bench_farm.py [--videos 4] [--workers 1,2] [--clips DIR]
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

from _package import ROOT, load_package


def clips(n: int, folder: str) -> str:
    """``folder`` with ``n`` 720p 10 s clips and their outlines beside them (generated if missing)."""
    os.makedirs(folder, exist_ok=True)
    load_package()
    from tree_from_video.sample_videos import synth_tree
    for k in range(n):
        video = os.path.join(folder, f"clip{k}.mp4")
        if os.path.exists(video):
            continue
        tmp = os.path.join(folder, f".gen{k}")
        synth_tree.generate(synth_tree.config_for("hd", width=1280, height=720, frames=240, seed=100 + k), tmp)
        shutil.move(os.path.join(tmp, "video.mp4"), video)
        shutil.move(os.path.join(tmp, "outline.json"), os.path.join(folder, f"clip{k}.outline.json"))
        shutil.rmtree(tmp)
    return folder


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--videos", type=int, default=4)
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--clips", default=os.path.join(tempfile.gettempdir(), "tfv_bench_farm_clips"))
    a = ap.parse_args()
    src = clips(a.videos, a.clips)
    rows, base = [], None
    for w in [int(x) for x in a.workers.split(",")]:
        out = tempfile.mkdtemp(prefix=f"tfv_farm_{w}_")
        t = time.perf_counter()
        p = subprocess.run([sys.executable, os.path.join(ROOT, "batch.py"), "--farm", src, "--out", out, "--workers",
                            str(w), "--npz", "--no-video"], capture_output=True, text=True)
        wall = time.perf_counter() - t
        farm = json.load(open(os.path.join(out, "farm.json")))
        ok = sum(j["status"] == "ok" for j in farm["jobs"])
        rss = max(json.load(open(os.path.join(j["out"], "report.json")))["peak_rss_mb"] for j in farm["jobs"])
        per_job = [j["seconds"] for j in farm["jobs"]]
        base = base or wall
        rows.append(f"| {w} | {ok}/{len(farm['jobs'])} | {wall:.0f} s | {min(per_job):.0f}–{max(per_job):.0f} s | "
                    f"**{3600 * ok / wall:.0f}** | {base / wall:.2f}× | {rss:.0f} MB |")
        if p.returncode != 0:
            print(p.stderr[-2000:], file=sys.stderr)
        shutil.rmtree(out)
    print(f"{a.videos} clips of 1280×720, 240 frames (10 s at 24 fps), batch.py --farm --npz --no-video, "
          f"local Dask cluster, {os.cpu_count()} cores")
    print("| workers | ok | wall | a job | videos per hour | speed-up | a job's peak RSS |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(r)


if __name__ == "__main__":
    main()
