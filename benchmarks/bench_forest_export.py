"""The panel's export of the default 12-tree forest (180 frames), one GLB per tree, in the real
Blender (issue 32: target ≤ 60 s on 2 cores), as the GUI runs it: background Blenders
(``operators/scene/export_process.py``), and for comparison in-process, one tree after the other.
Needs a Blender binary (the bpy module has none to start)::

    ../shared/tools/real-blender run blender -b --factory-startup \
        --python benchmarks/bench_forest_export.py [-- --only background]

Prints the wall time of each way and the trees' count; the files go to a temporary folder.
"""
import argparse
import os
import shutil
import sys
import tempfile
import time

import bpy

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests", "gui"))
from _addon import register_with_sample  # noqa: E402

TARGET_S = 60.0


def main() -> None:
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", choices=("background", "inprocess"), default=None)
    args = ap.parse_args(argv)
    register_with_sample()
    assert bpy.ops.tree_video.generate_forest("EXEC_DEFAULT") == {"FINISHED"}
    from tree_from_video.operators import export_op, jobs
    colls = sorted((c for c in bpy.data.collections if c.name.startswith("Forest ")), key=lambda c: c.name)
    frames = bpy.context.scene.frame_end - bpy.context.scene.frame_start + 1
    rows = []
    for way in ("background", "inprocess"):
        if args.only not in (None, way):
            continue
        out = tempfile.mkdtemp(prefix=f"tfv_forest_{way}_")
        items = [(c, os.path.join(out, f"{c.name.replace(' ', '_')}.glb")) for c in colls]
        t = time.perf_counter()
        job = jobs.SteppedJob(export_op.export_steps(items, "GLB", False, False,
                                                     background=way == "background")).run_here()
        seconds = time.perf_counter() - t
        written = sum(os.path.isfile(p) for _, p in items)
        rows.append((way, seconds, written, job.result.timing() if job.result else "", job.error))
        shutil.rmtree(out, ignore_errors=True)
    print(f"\nthe default forest: {len(colls)} trees, {frames} frames, one GLB each (target ≤ {TARGET_S:.0f} s)")
    print("| export | s | files | as the panel shows it | error |")
    print("|---|---|---|---|---|")
    for way, seconds, written, timing, error in rows:
        print(f"| {way} | {seconds:.1f} | {written} | {timing} | {error or '—'} |", flush=True)


main()
