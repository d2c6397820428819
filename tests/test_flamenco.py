"""The Flamenco 3 job type (docs/farm/tree_from_video.js, issue 34), compiled by node against the
author API Flamenco documents (tests/flamenco_author.mjs): a task per video of type ``blender``
with one ``blender-render`` command whose arguments run the add-on's batch entry; the job folders
named as the batch's own farm names them; the command of one task run for real (its batch part
here with the venv's Python; the whole command in the real Blender 4.3 by scripts/test_blender.sh)."""
import json
import os
import shutil
import subprocess
import sys

from job_report import check_report

from tree_from_video.core.farm import inputs

from samples import ROOT, committed

COMPILER = os.path.join(ROOT, "docs", "farm", "tree_from_video.js")
HARNESS = os.path.join(ROOT, "tests", "flamenco_author.mjs")


def compile_job(tmp_path, settings: dict) -> dict:
    f = tmp_path / "settings.json"
    f.write_text(json.dumps(settings))
    p = subprocess.run(["node", HARNESS, COMPILER, str(f)], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)


def test_a_task_per_video_named_as_the_farm_names_them(tmp_path):
    videos = ["/clips/a.mp4", "/clips/b.mov", "/other/a.mp4"]
    job = compile_job(tmp_path, {"videos": "\n".join(videos) + "\n# a comment\n", "out_dir": "/out",
                                 "batch_py": "/ext/batch.py", "outline": "beside", "bones": 64, "gltf": True,
                                 "preview": False, "engine": "godot", "extra": "--frames 0:24  --no-video"})
    assert {"videos", "out_dir", "batch_py", "outline", "bones", "engine"} <= set(job["settings"])
    names = inputs.unique_names([os.path.splitext(os.path.basename(v))[0] for v in videos])
    assert [t["name"] for t in job["tasks"]] == [f"tree-{n}" for n in names] == ["tree-a", "tree-b", "tree-a-2"]
    for t, video, name in zip(job["tasks"], videos, names):
        assert t["type"] == "blender" and [c["name"] for c in t["commands"]] == ["blender-render"]
        p = t["commands"][0]["parameters"]
        assert p["exe"] == "{blender}" and p["exeArgs"] == "{blenderArgs}"
        args = p["args"]
        assert args[:5] == ["--python-exit-code", "1", "--python", "/ext/batch.py", "--"]
        batch = args[5:]
        assert batch[0] == video and batch[batch.index("--out") + 1] == f"/out/{name}"
        assert batch[batch.index("--outline") + 1] == os.path.splitext(video)[0] + ".outline.json"
        assert batch[batch.index("--bones") + 1] == "64" and batch[batch.index("--engine") + 1] == "godot"
        assert "--gltf" in batch and "--preview" not in batch and batch[-3:] == ["--frames", "0:24", "--no-video"]


def test_an_empty_job_is_refused(tmp_path):
    job = compile_job(tmp_path, {"videos": "\n# nothing\n", "out_dir": "/out", "batch_py": "/ext/batch.py"})
    assert "no video" in job["error"]


def test_the_batch_part_of_a_task_runs_for_real(tmp_path):
    clips = tmp_path / "clips"
    clips.mkdir()
    shutil.copy(os.path.join(committed("broad"), "video.mp4"), clips / "oak.mp4")
    shutil.copy(os.path.join(committed("broad"), "outline.json"), clips / "oak.outline.json")
    job = compile_job(tmp_path, {"videos": str(clips / "oak.mp4"), "out_dir": str(tmp_path / "out"),
                                 "batch_py": os.path.join(ROOT, "batch.py"), "gltf": False, "preview": False,
                                 "extra": "--frames 0:24 --no-video --levels 4 --twigs 0 --quiet"})
    args = job["tasks"][0]["commands"][0]["parameters"]["args"]
    cut = args.index("--")
    p = subprocess.run([sys.executable, args[cut - 1], *args[cut + 1:]], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert check_report(tmp_path / "out" / "oak")["status"] == "ok"
