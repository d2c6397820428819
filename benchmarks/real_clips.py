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
from dataclasses import dataclass

import numpy as np

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "real_footage")
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
