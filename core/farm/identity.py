"""What makes two runs the same job: the input files' content (SHA-256: the video, the outline, and
the files the settings name, ``side_sha256``) and the settings (a hash of their canonical JSON), and
the decision a re-run takes from the report a folder holds."""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass

#: bytes read at a time when hashing a video
CHUNK = 1 << 20


def file_sha256(path: str | os.PathLike) -> str:
    """The hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(CHUNK), b""):
            h.update(block)
    return h.hexdigest()


def settings_hash(settings: dict) -> str:
    """The hex SHA-256 of ``settings`` as canonical JSON (sorted keys, no spaces)."""
    return hashlib.sha256(json.dumps(settings, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def input_identity(video: str | None, outline: str | None) -> dict | None:
    """``{"video", "bytes", "sha256", "outline", "outline_sha256"}`` of a job's inputs (an outline
    that is not a file, like ``auto``, is named without a hash); None without a readable video."""
    if not video or not os.path.isfile(video):
        return None
    doc = {"video": os.path.abspath(video), "bytes": os.path.getsize(video), "sha256": file_sha256(video),
           "outline": outline, "outline_sha256": None}
    if outline and os.path.isfile(outline):
        doc["outline"] = os.path.abspath(outline)
        doc["outline_sha256"] = file_sha256(outline)
    return doc


def files_identity(paths, key: str) -> dict | None:
    """``{key: [{"file", "bytes", "sha256"}...], "sha256"}`` of a job's input files that are not a video (the
    exemplars of variations); None when one is missing (the run names it)."""
    if not paths or not all(os.path.isfile(p) for p in paths):
        return None
    files = [{"file": os.path.abspath(p), "bytes": os.path.getsize(p), "sha256": file_sha256(p)} for p in paths]
    joined = hashlib.sha256("".join(f["sha256"] for f in files).encode()).hexdigest()
    return {key: files, "sha256": joined}           # "sha256" of them all: what decide() compares


@dataclass
class Decision:
    """What a run does with its folder: ``action`` is ``run`` (nothing of ours there), ``skip`` (a
    finished job with the same settings and input) or ``redo`` (our earlier run did not finish:
    its files are ours to write over); ``why`` one line for the user."""

    action: str
    why: str


def decide(prior: dict | None, settings_sha: str, input_doc: dict | None, force: bool) -> Decision:
    """The :class:`Decision` for a job whose folder holds the report ``prior`` (None: none)."""
    if prior is None:
        return Decision("run", "no report yet")
    status = prior.get("status")
    before, now = prior.get("input") or {}, input_doc or {}
    same = (prior.get("settings_sha256") == settings_sha
            and all(before.get(k) == now.get(k) for k in ("sha256", "outline_sha256", "side_sha256")))
    if status == "ok":
        if same and not force:
            return Decision("skip", "done: report.json is ok with the same settings and input (--force runs it again)")
        if same:
            return Decision("redo", "done, run again (--force)")
        return Decision("run", "report.json is ok but for other settings or input")
    return Decision("redo", f"the last run ended '{status}': run again from scratch")
