"""batch.py end to end: a real run, and every bad input → exit 2, one line, nothing written."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from job_report import check_report

from samples import ROOT, committed

pytestmark = [pytest.mark.bpy53]

BATCH = os.path.join(ROOT, "batch.py")
VIDEO = os.path.join(committed("broad"), "video.mp4")
OUTLINE = os.path.join(committed("broad"), "outline.json")


def run(*args):
    p = subprocess.run([sys.executable, BATCH, *map(str, args)], capture_output=True, text=True, timeout=600)
    return p.returncode, p.stdout, p.stderr


def test_batch_writes_skeleton_overlays_and_result(tmp_path):
    out = tmp_path / "out"
    code, _, err = run(VIDEO, "--outline", OUTLINE, "--out", out, "--npz", "--frames", "0:48", "--levels", "5")
    assert code == 0, err
    assert sorted(os.listdir(out)) == ["job.log", "overlay.mp4", "overlay.png", "report.json", "result.npz",
                                       "skeleton.npz", "tree3d.npz"]
    doc = check_report(out)
    assert doc["status"] == "ok" and {o["path"] for o in doc["outputs"]} == {
        "overlay.mp4", "overlay.png", "result.npz", "skeleton.npz", "tree3d.npz"}
    with np.load(out / "result.npz", allow_pickle=False) as z:
        F, N = z["nodes2d"].shape[:2]
        assert F == 48 and z["nodes2d"].shape[2] == 2 and z["parents"].shape == (N,) and z["level"].shape == (N,)
        assert z["parents"][0] == -1 and float(z["fps"]) == pytest.approx(24.0)
    assert "[tracking]" in err and "done:" in err
    import cv2
    cap = cv2.VideoCapture(str(out / "overlay.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 48
    cap.release()
    # a second run refuses to overwrite without --force, and keeps the files
    before = (out / "skeleton.npz").stat().st_mtime_ns
    code, _, err = run(VIDEO, "--outline", OUTLINE, "--out", out)
    assert code == 2 and "--force" in err
    assert (out / "skeleton.npz").stat().st_mtime_ns == before


def test_paper_skeleton_option(tmp_path):
    code, _, err = run(VIDEO, "--outline", OUTLINE, "--out", tmp_path / "p", "--skeleton", "paper",
                       "--frames", ":24", "--no-video")
    assert code == 0, err
    assert sorted(os.listdir(tmp_path / "p")) == ["job.log", "overlay.png", "report.json", "skeleton.npz", "tree3d.npz"]
    assert check_report(tmp_path / "p")["settings"]["skeleton"] == "paper"
    with np.load(tmp_path / "p" / "skeleton.npz", allow_pickle=False) as z:
        assert json.loads(str(z["meta_json"]))["kind"] == "paper"


def test_help_documents_every_option():
    code, out, _ = run("--help")
    assert code == 0
    for opt in ("--outline", "--out", "--npz", "--levels", "--frames", "--skeleton", "--scale", "--force"):
        assert opt in out


def _bad_inputs(tmp):
    text = tmp / "notavideo.mp4"
    text.write_text("hello")
    empty = tmp / "empty.mp4"
    empty.write_bytes(b"")
    def outline(name, data):
        p = tmp / name
        p.write_text(data if isinstance(data, str) else json.dumps(data))
        return p
    blank = tmp / "blank.png"
    import cv2
    cv2.imwrite(str(blank), np.zeros((360, 480), np.uint8))
    afile = tmp / "afile"
    afile.write_text("x")
    return {
        "missing video": ([tmp / "nope.mp4", "--outline", OUTLINE], "does not exist"),
        "unreadable video": ([text, "--outline", OUTLINE], "cannot be read"),
        "zero-frame video": ([empty, "--outline", OUTLINE], "cannot be read"),
        "missing outline": ([VIDEO, "--outline", tmp / "none.json"], "does not exist"),
        "outline not json": ([VIDEO, "--outline", outline("bad.json", "{nope")], "JSON"),
        "outline empty": ([VIDEO, "--outline", outline("empty.json", [])], "point"),
        "outline degenerate": ([VIDEO, "--outline", outline("line.json", [[10, 10], [50, 50], [90, 90]])], "degenerate"),
        "outline outside": ([VIDEO, "--outline", outline("out.json", [[1000, 1000], [1100, 1000], [1100, 1100]])], "outside"),
        "outline mask blank": ([VIDEO, "--outline", blank], "empty"),
        "out is a file": ([VIDEO, "--outline", OUTLINE, "--out", afile / "sub"], "--out"),
        # as root os.access says yes where makedirs fails: refused before any work (no progress line)
        "out cannot be created": ([VIDEO, "--outline", OUTLINE, "--out", "/proc/tfv-out/x"], "cannot be created"),
        "generate out cannot be created": (["--generate", "2", "--species", "broad", "--out", "/proc/tfv-out"],
                                           "cannot be created"),
        "unknown option": ([VIDEO, "--outline", OUTLINE, "--bogus"], "unrecognized"),
        "bad frames": ([VIDEO, "--outline", OUTLINE, "--frames", "5"], "frame range"),
        "bad levels": ([VIDEO, "--outline", OUTLINE, "--levels", "1"], "levels"),
        "bad scale": ([VIDEO, "--outline", OUTLINE, "--scale", "0"], "scale"),
        "unknown limb species": ([VIDEO, "--outline", OUTLINE, "--limbs", "grow", "--limb-species", "oak"], "species"),
        "too many lods": ([VIDEO, "--outline", OUTLINE, "--gltf", "--lods", "9"], "--lods"),
        "lods without outputs": ([VIDEO, "--outline", OUTLINE, "--lods", "3"], "--lods"),
        "viewer without gltf": ([VIDEO, "--outline", OUTLINE, "--fbx", "--viewer"], "--gltf"),
        "unknown engine": ([VIDEO, "--outline", OUTLINE, "--engine", "cryengine"], "engine"),
        "zero bones": ([VIDEO, "--outline", OUTLINE, "--gltf", "--bones", "0"], "--bones"),
    }


BAD_CASES = [
    "missing video", "unreadable video", "zero-frame video", "missing outline", "outline not json",
    "outline empty", "outline degenerate", "outline outside", "outline mask blank", "out is a file",
    "out cannot be created", "generate out cannot be created", "unknown option", "bad frames", "bad levels", "bad scale",
    "unknown limb species", "too many lods", "lods without outputs", "viewer without gltf", "unknown engine",
    "zero bones"]


@pytest.mark.parametrize("case", BAD_CASES)
def test_bad_input_exits_2_with_one_line(tmp_path, case):
    assert set(BAD_CASES) == set(_bad_inputs(tmp_path))
    inputs = tmp_path / "in"
    inputs.mkdir()
    args, needle = _bad_inputs(inputs)[case]
    out = tmp_path / "out"
    if "--out" not in args:
        args = [*args, "--out", out]
    code, stdout, err = run(*args)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, (case, err)
    assert len(lines) == 1 and lines[0].startswith("error:"), (case, err)
    assert needle.lower() in lines[0].lower(), (case, lines[0])
    assert "Traceback" not in err
    assert not out.exists(), case
