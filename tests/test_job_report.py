"""Every batch job leaves report.json and job.log (core/farm/report.py, issue 34), and a re-run of
a finished job is skipped (core/farm/identity.py): the report checked against its schema and
against the files and the video it describes; a killed run redone; bad input reported only where
it cannot hide a finished job; a job given as a file, and every way such a file can be wrong."""
import hashlib
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from job_report import check_report

from tree_from_video import cli
from tree_from_video.core import jobs
from tree_from_video.core.farm import identity

from samples import ROOT, committed

pytestmark = [pytest.mark.bpy53]

BATCH = os.path.join(ROOT, "batch.py")
VIDEO = os.path.join(committed("broad"), "video.mp4")
OUTLINE = os.path.join(committed("broad"), "outline.json")
QUICK = ["--frames", "0:24", "--no-video", "--levels", "4", "--twigs", "0"]


def run(*args, timeout=600):
    p = subprocess.run([sys.executable, BATCH, *map(str, args)], capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def test_a_run_reports_what_it_did_and_a_rerun_skips(tmp_path):
    out = tmp_path / "out"
    code, _, err = run(VIDEO, "--outline", OUTLINE, "--out", out, "--npz", *QUICK)
    assert code == 0, err
    doc = check_report(out)
    assert doc["status"] == "ok" and doc["message"] is None and doc["warnings"] == []
    data = open(VIDEO, "rb").read()
    assert doc["input"]["sha256"] == hashlib.sha256(data).hexdigest() and doc["input"]["bytes"] == len(data)
    assert doc["video"] == {"width": 480, "height": 360, "fps": 24.0, "frames": [0, 24], "time_base": doc["video"]["time_base"]}
    with np.load(out / "tree3d.npz", allow_pickle=False) as z:
        assert doc["counts"]["nodes"] == z["nodes3d"].shape[1]
    assert f"{doc['counts']['tracks']} tracks" in err                      # the count the run printed
    assert {o["path"]: o["bytes"] for o in doc["outputs"]} == {
        f: os.path.getsize(out / f) for f in os.listdir(out) if f not in ("report.json", "job.log")}
    assert {"tracking", "skeleton", "lift", "motion"} <= set(doc["stages"])
    assert 0 < sum(doc["stages"].values()) <= doc["seconds"]
    assert doc["versions"]["numpy"] == np.__version__ and doc["peak_rss_mb"] > 50
    assert "done:" in (out / "job.log").read_text()
    assert doc["settings"]["levels"] == 4 and doc["settings_sha256"] == identity.settings_hash(doc["settings"])
    # the same job again: skipped, the report untouched; --dry-run says so; --force runs it
    before = (out / "report.json").read_bytes()
    code, _, err = run(VIDEO, "--outline", OUTLINE, "--out", out, "--npz", *QUICK)
    assert code == 0 and err.startswith("skipped:") and (out / "report.json").read_bytes() == before
    assert run(VIDEO, "--outline", OUTLINE, "--out", out, "--npz", *QUICK, "--dry-run")[1].startswith("skip:")
    assert run(VIDEO, "--outline", OUTLINE, "--out", out, "--npz", *QUICK, "--force", "--dry-run")[1].startswith("redo:")
    # other settings into the done folder: refused as before, and the done job's report kept
    code, _, err = run(VIDEO, "--outline", OUTLINE, "--out", out, *QUICK[:-2])
    assert code == 2 and "--force" in err and (out / "report.json").read_bytes() == before


def test_a_killed_run_says_so_and_is_redone(tmp_path):
    out = tmp_path / "out"
    args = [sys.executable, BATCH, VIDEO, "--outline", OUTLINE, "--out", str(out), "--no-video", "--quiet"]
    p = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not (out / "report.json").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait()
    doc = check_report(out)
    assert doc["status"] == "running" and doc["outputs"] == []
    code, stdout, _ = run(VIDEO, "--outline", OUTLINE, "--out", out, "--no-video", "--quiet", "--dry-run")
    assert code == 0 and stdout.startswith("redo:") and "'running'" in stdout
    code, _, err = run(VIDEO, "--outline", OUTLINE, "--out", out, "--no-video", "--quiet")
    assert code == 0, err
    assert check_report(out)["status"] == "ok"


def test_bad_input_is_reported_into_an_existing_folder(tmp_path):
    out = tmp_path / "farm" / "clip"
    out.mkdir(parents=True)                          # a farm makes the job's folder before it runs
    code, _, err = run(VIDEO, "--outline", tmp_path / "none.json", "--out", out)
    assert code == 2 and len(err.strip().splitlines()) == 1
    doc = check_report(out)
    assert doc["status"] == "bad_input" and "does not exist" in doc["message"] and doc["outputs"] == []
    assert doc["message"] in (out / "job.log").read_text()
    # a second bad run replaces a failure's report; a missing folder stays missing
    code, _, _ = run(VIDEO, "--outline", OUTLINE, "--out", out, "--levels", "1")
    assert code == 2 and "levels" in check_report(out)["message"]
    code, _, _ = run(VIDEO, "--outline", OUTLINE, "--out", tmp_path / "nowhere", "--levels", "1")
    assert code == 2 and not (tmp_path / "nowhere").exists()


def test_a_job_file_runs_like_its_command_line(tmp_path):
    out = tmp_path / "out"
    job = tmp_path / "job.json"
    job.write_text(json.dumps({"video": VIDEO, "outline": OUTLINE, "out": str(out), "frames": "0:24",
                               "no_video": True, "levels": 4, "twigs": 0}))
    code, _, err = run("--job", job)
    assert code == 0, err
    doc = check_report(out)
    assert doc["status"] == "ok" and doc["command"] == ["--job", str(job)] and doc["settings"]["levels"] == 4
    # the same job on its command line is the same job: skipped
    code, _, err = run(VIDEO, "--outline", OUTLINE, "--out", out, *QUICK)
    assert code == 0 and err.startswith("skipped:"), err


BAD_JOBS = {
    "unknown key": ({"video": VIDEO, "outline": OUTLINE, "out": "{out}", "colour": "red"}, "unknown key 'colour'"),
    "wrong type": ({"video": VIDEO, "outline": OUTLINE, "out": "{out}", "levels": "six"}, "'levels'"),
    "switch not bool": ({"video": VIDEO, "outline": OUTLINE, "out": "{out}", "gltf": 1}, "true or false"),
    "not an object": ([VIDEO], "no JSON object"),
    "missing video": ({"video": "{tmp}/nope.mp4", "outline": OUTLINE, "out": "{out}"}, "does not exist"),
    "no out": ({"video": VIDEO, "outline": OUTLINE}, "--out"),
    "not json": ("{nope", "not readable JSON"),
    "missing job file": (None, "does not exist"),
}


@pytest.mark.parametrize("case", sorted(BAD_JOBS))
def test_a_bad_job_file_is_one_line_exit_2(tmp_path, case):
    doc, needle = BAD_JOBS[case]
    job = tmp_path / "job.json"
    if doc is not None:
        text = doc if isinstance(doc, str) else json.dumps(doc)
        job.write_text(text.replace("{out}", str(tmp_path / "out")).replace("{tmp}", str(tmp_path)))
    code, _, err = run("--job", job)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error:"), (case, err)
    assert needle.lower() in lines[0].lower(), (case, lines[0])
    assert not (tmp_path / "out").exists()
    code, _, err = run("--job", job, "--levels", "4")           # options go in the file, not beside it
    assert code == 2 and "beside --job" in err


def test_the_rerun_decision():
    v = {"sha256": "a" * 64, "outline_sha256": None}
    ok = {"status": "ok", "settings_sha256": "s", "input": v}
    assert identity.decide(None, "s", v, False).action == "run"
    assert identity.decide(ok, "s", v, False).action == "skip"
    assert identity.decide(ok, "s", v, True).action == "redo"
    assert identity.decide(ok, "t", v, False).action == "run"                     # other settings
    assert identity.decide(ok, "s", {"sha256": "b" * 64, "outline_sha256": None}, False).action == "run"
    for status in ("running", "bad_input", "error", "cancelled"):
        assert identity.decide(dict(ok, status=status), "s", v, False).action == "redo"
    assert identity.decide(ok, "s", dict(v, side_sha256="c" * 64), False).action == "run"   # a cut changed


def test_a_changed_cut_or_bark_photo_is_another_input(tmp_path):
    """The files a job's settings name (a cut, bark photos in a folder) are hashed into its input
    identity: the same settings with a cut file rewritten, or a photo added to the folder, are not
    skipped."""
    cut, photos = tmp_path / "limb.npz", tmp_path / "bark"
    cut.write_bytes(b"one")
    photos.mkdir()
    (photos / "a.jpg").write_bytes(b"a")
    argv = [VIDEO, "--outline", OUTLINE, "--generate", "2", "--out", str(tmp_path / "out"), "--cut", f"{cut}@0,0,1",
            "--bark-image", str(photos)]
    job = jobs.from_flat(cli.options(cli.build_parser().parse_args(argv)), "the job")
    first = cli.record(job, argv)
    assert [os.path.basename(f["file"]) for f in first.input["side_files"]] == ["a.jpg", "limb.npz"]   # SIDE_FILES order
    prior = {"status": "ok", "settings_sha256": first.settings_sha256, "input": first.input}
    assert identity.decide(prior, first.settings_sha256, cli.record(job, argv).input, False).action == "skip"
    cut.write_bytes(b"two")
    assert identity.decide(prior, first.settings_sha256, cli.record(job, argv).input, False).action == "run"
    cut.write_bytes(b"one")
    (photos / "b.jpg").write_bytes(b"b")
    assert identity.decide(prior, first.settings_sha256, cli.record(job, argv).input, False).action == "run"


def test_job_argv_follows_the_parser():
    argv = cli.job_argv({"video": "v.mp4", "out": "o", "gltf": True, "fbx": False, "bones": 64, "loop": 10,
                         "leaf-density": 0.5}, "j.json")
    assert argv[0] == "v.mp4" and "--gltf" in argv and "--fbx" not in argv
    assert argv[argv.index("--bones") + 1] == "64" and argv[argv.index("--loop") + 1] == "10"
    assert argv[argv.index("--leaf-density") + 1] == "0.5"
    args = cli.build_parser().parse_args(argv)
    assert args.bones == 64 and args.loop == 10.0 and args.gltf and args.leaf_density == 0.5


def test_the_exports_step_runs_alone_from_a_saved_tree(tmp_path):
    """A farm can run the video on any worker and the Blender outputs on Blender workers: the
    second step builds them from the first's tree3d.npz, with its own report."""
    core, exports = tmp_path / "core", tmp_path / "exports"
    code, _, err = run(VIDEO, "--outline", OUTLINE, "--out", core, *QUICK, "--quiet")
    assert code == 0, err
    code, _, err = run("--tree", core / "tree3d.npz", "--out", exports, "--gltf", "--bones", "16", "--quiet")
    assert code == 0, err
    doc = check_report(exports)
    assert doc["status"] == "ok" and [o["path"] for o in doc["outputs"]] == ["tree.glb"]
    assert doc["counts"]["bones"] == 16 and doc["counts"]["triangles"] > 1000
    assert doc["input"]["sha256"] == hashlib.sha256((core / "tree3d.npz").read_bytes()).hexdigest()
    assert run("--tree", core / "tree3d.npz", "--out", exports, "--gltf", "--bones", "16")[2].startswith("skipped:")
    for args, needle in (([], "add one of"), (["--gltf", "--outline", OUTLINE], "drop the VIDEO"),):
        code, _, err = run("--tree", core / "tree3d.npz", "--out", tmp_path / "x", *args)
        assert code == 2 and needle in err and len(err.strip().splitlines()) == 1, err
    code, _, err = run("--tree", tmp_path / "none.npz", "--out", tmp_path / "x", "--gltf")
    assert code == 2 and "does not exist" in err
