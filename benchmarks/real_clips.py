"""The real clips of ``benchmarks/real_footage/clips.json`` (issue 31): where they come from, the
file the benchmarks read, and their outlines and masks, for ``real_footage.py`` and
``real_robustness.py``.

The clips are public files of other repositories whose rights are unclear: they are fetched for
development and never committed. Put them in one folder, each named after its key in clips.json
(``trees.mp4``, ``tree1080.mp4``, ``palm_below.mp4``, ``webcam.avi``) or, for a clip with an
``encode`` recipe, its source frames in ``<key>/`` (``wavingtrees/b00000.bmp``…); ``prepare``
encodes those once into ``<key>.mp4``. From a clone of the source repository at its commit::

    git -C REPO show COMMIT:PATH > CLIPS/KEY.mp4
"""
from __future__ import annotations

import glob
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass

import numpy as np

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "real_footage")
BATCH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "batch.py")
EXTS = (".mp4", ".avi", ".mov", ".mkv")


@dataclass
class RealClip:
    """One real clip: ``key`` (clips.json), ``video`` path, ``outline (P, 2)`` frame-1 pixels,
    ``mask`` path of the crown's frame-1 pixels (or None), ``kind`` and the ``form`` to ask for."""
    key: str
    video: str
    outline: np.ndarray
    mask: str | None
    kind: str
    form: str
    notes: str


def catalogue() -> dict:
    """clips.json's ``clips``."""
    with open(os.path.join(HERE, "clips.json")) as f:
        return json.load(f)["clips"]


def _encoded(folder: str, key: str, recipe: list[str]) -> str | None:
    """``<folder>/<key>.mp4`` encoded from the frames in ``<folder>/<key>/`` by ``recipe`` (once)."""
    out = os.path.join(folder, key + ".mp4")
    if os.path.exists(out):
        return out
    frames = sorted(glob.glob(os.path.join(folder, key, "*")))
    if not frames:
        return None
    pattern = os.path.join(folder, key, "b%05d" + os.path.splitext(frames[0])[1])
    args = [a.replace("{src}", pattern) for a in recipe]
    subprocess.run(["ffmpeg", "-v", "error", "-y", *args, out], check=True)
    return out


def prepare(folder: str) -> list[RealClip]:
    """The clips of ``folder`` that clips.json knows (encoded where a recipe says so), in its order."""
    found = []
    for key, c in catalogue().items():
        video = next((os.path.join(folder, key + e) for e in EXTS if os.path.exists(os.path.join(folder, key + e))),
                     None)
        if video is None and c.get("encode"):
            video = _encoded(folder, key, c["encode"])
        if video is None:
            continue
        mask = os.path.join(HERE, key + "_mask.png")
        found.append(RealClip(key, video, np.asarray(c["outline"], float), mask if os.path.exists(mask) else None,
                              c["kind"], c.get("form", "auto"), c.get("notes", "")))
    return found


def write_outline(poly: np.ndarray, path: str) -> str:
    """Write ``poly (P, 2)`` pixels as an outline .json; returns ``path``."""
    with open(path, "w") as f:
        json.dump(np.round(np.asarray(poly, float), 1).tolist(), f)
    return path


def select(folder: str, only: str = "") -> list[RealClip]:
    """:func:`prepare`'s clips of ``folder``, those named in ``only`` (comma-separated keys) when
    given; exits with one line (code 2) when there is none."""
    clips = [c for c in prepare(folder) if not only or c.key in only.split(",")]
    if not clips:
        print(f"error: no clip of benchmarks/real_footage/clips.json in {folder}", file=sys.stderr)
        raise SystemExit(2)
    return clips


@dataclass
class BatchRun:
    """One batch run: exit code, wall seconds, its ``warning:`` lines and its last line."""
    code: int
    seconds: float
    warnings: list[str]
    last: str


def run_batch(video: str, outline: str, out: str, form: str, *extra: str) -> BatchRun:
    """Run ``batch.py VIDEO --outline OUTLINE --out OUT --no-video --force --form FORM [EXTRA]``."""
    cmd = [sys.executable, BATCH, video, "--outline", outline, "--out", out, "--no-video", "--force",
           "--form", form, *extra]
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip() and not ln.startswith("[")]
    return BatchRun(p.returncode, time.perf_counter() - t, [ln for ln in lines if ln.startswith("warning:")],
                    lines[-1] if lines else "")
