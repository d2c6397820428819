"""Inside the real Blender 4.3 (``blender -b --python tests/blender/background_export.py``; the bpy
module has no Blender binary to start): the panel's export in background Blenders
(``operators/scene/export_process.py``) writes what the in-process export writes, and a worker that
fails reports its one line and leaves no file. Exits 1 on a failed check; prints lines CI greps."""
import json
import os
import shutil
import struct
import sys
import tempfile

import bpy

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "tests", "gui"))
from _addon import register_with_sample  # noqa: E402

props = register_with_sample()
props.species_source, props.species_name = "LIBRARY", "broad"
props.gen_nodes, props.gen_frames, props.gen_height = 120, 24, 8.0
props.forest_count = 3
assert bpy.ops.tree_video.generate_forest("EXEC_DEFAULT") == {"FINISHED"}

from tree_from_video.operators import export_op, jobs  # noqa: E402

colls = sorted((c for c in bpy.data.collections if c.name.startswith("Forest ")), key=lambda c: c.name)
out = tempfile.mkdtemp(prefix="tfv_bg_export_")


def run(items, background: bool):
    return jobs.SteppedJob(export_op.export_steps(items, "GLB", False, False, background=background)).run_here()


def joints_and_frames(path):
    data = open(path, "rb").read()
    n = struct.unpack("<I", data[12:16])[0]
    doc = json.loads(data[20:20 + n])
    anim = doc["animations"][0]
    times = doc["accessors"][anim["samplers"][0]["input"]]["count"]
    return len(doc["skins"][0]["joints"]), times, sorted(m["name"] for m in doc["materials"])


ok = True
items = [(c, os.path.join(out, f"bg_{k}.glb")) for k, c in enumerate(colls)]
job = run(items, background=True)
same = [(c, os.path.join(out, f"in_{k}.glb")) for k, c in enumerate(colls)]
job_in = run(same, background=False)
if job.error or job_in.error:
    print(f"background export failed: {job.error} / {job_in.error}", flush=True)
    ok = False
else:
    for (_, a), (_, b) in zip(items, same):
        if joints_and_frames(a) != joints_and_frames(b):
            print(f"background and in-process exports differ: {joints_and_frames(a)} vs {joints_and_frames(b)}")
            ok = False
    print(f"background export: {len(items)} files, joints/frames/materials as in-process: {ok}", flush=True)

# a worker that fails (its folder removed under it): one clear line, no file left
gone = os.path.join(out, "gone")
os.makedirs(gone)
bad = [(colls[0], os.path.join(gone, "tree.glb"))]
steps = export_op.export_steps(bad, "GLB", False, False, background=True)
job = jobs.SteppedJob(steps)
job.tick()                                   # the worker starts
shutil.rmtree(gone)
job.run_here()
print(f"failed worker: {job.error}", flush=True)
if not job.error or "no file written" not in job.error or "does not exist" not in job.error or os.path.exists(gone):
    ok = False

# one process writing two trees whose second fails: the error names it, the first is not left either
from tree_from_video.operators.scene import export_process  # noqa: E402

export_process.PARALLEL = 1
os.makedirs(gone)
pair = [(colls[0], os.path.join(out, "first.glb")), (colls[1], os.path.join(gone, "second.glb"))]
job = jobs.SteppedJob(export_op.export_steps(pair, "GLB", False, False, background=True))
job.tick()                                   # the worker starts
shutil.rmtree(gone)
job.run_here()
left = [f for f in os.listdir(out) if f.startswith(("first", ".first"))]
print(f"failed second tree: {job.error}; files left: {left}", flush=True)
if not job.error or not job.error.startswith(f"'{colls[1].name}'") or left:
    ok = False
print(f"background export checks passed: {ok}", flush=True)
shutil.rmtree(out, ignore_errors=True)
sys.exit(0 if ok else 1)
