"""What a farm runs: the videos of a folder, a list file or a jobs file, each with its outline
and its own output folder ``DIR/<stem>/`` (names made unique in a stable order, so a re-run finds
the same folders)."""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Callable

from ..errors import InputError
from ..fileio import read_json

#: the files of a folder a farm takes as videos (any case)
VIDEO_EXTENSIONS = (".mp4", ".mov", ".m4v", ".avi", ".mkv", ".webm", ".mts")
#: an outline beside a video: ``<stem>.outline.json`` or ``<stem>.mask.png``
OUTLINE_SUFFIXES = (".outline.json", ".mask.png")


@dataclass
class FarmJob:
    """One job of a farm: ``name`` its folder's name under the farm's output, ``video`` and
    ``outline`` (None: none found; the job then fails as bad input), ``out`` its folder, ``argv``
    the batch command line that runs it (without the program)."""

    name: str
    video: str | None
    outline: str | None
    out: str
    argv: list[str] = field(default_factory=list)


def outline_for(video: str, default: str | None) -> str | None:
    """The outline beside ``video`` (``<stem>.outline.json``, then ``<stem>.mask.png``), else
    ``default`` (a file or ``auto``)."""
    stem = os.path.splitext(video)[0]
    for suffix in OUTLINE_SUFFIXES:
        if os.path.isfile(stem + suffix):
            return stem + suffix
    return default


def unique_names(stems: list[str]) -> list[str]:
    """``stems`` made unique in order: a repeated ``clip`` becomes ``clip-2``, ``clip-3``…"""
    seen: set[str] = set()
    out = []
    for s in stems:
        name, k = s, 1
        while name in seen:
            k += 1
            name = f"{s}-{k}"
        seen.add(name)
        out.append(name)
    return out


def read_source(source: str) -> list[dict]:
    """The entries of a farm's source: a folder (its videos, sorted), a list file (a video path a
    line; ``#`` comments; relative paths from the list's folder) or a ``.json`` file (a list of job
    objects, each with at least ``video`` or ``generate``). Each entry is a dict of job options.
    :class:`InputError` for a missing or empty source."""
    if os.path.isdir(source):
        videos = sorted(os.path.join(source, f) for f in os.listdir(source)
                        if f.lower().endswith(VIDEO_EXTENSIONS) and os.path.isfile(os.path.join(source, f)))
        if not videos:
            raise InputError(f"--farm folder '{source}' holds no video ({', '.join(VIDEO_EXTENSIONS)}); "
                             "give a folder of clips, a list file or a jobs .json")
        return [{"video": v} for v in videos]
    if not os.path.isfile(source):
        raise InputError(f"--farm '{source}' does not exist; give a folder of videos, a list file or a jobs .json")
    base = os.path.dirname(os.path.abspath(source))
    if source.lower().endswith(".json"):
        doc = read_json(source, f"jobs file '{source}'", "write a JSON list of job objects")
        if not isinstance(doc, list) or not doc or not all(isinstance(d, dict) for d in doc):
            raise InputError(f"jobs file '{source}' is not a list of job objects; write "
                             '[{"video": "a.mp4"}, {"video": "b.mp4", "bones": 64}]')
        return [dict(d) for d in doc]
    try:
        with open(source, encoding="utf-8") as fh:
            lines = [ln.strip() for ln in fh]
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"list file '{source}' cannot be read ({exc.__class__.__name__}); give a text file "
                         "of video paths") from None
    videos = [ln if os.path.isabs(ln) else os.path.join(base, ln) for ln in lines if ln and not ln.startswith("#")]
    if not videos:
        raise InputError(f"list file '{source}' names no video; write one video path a line")
    return [{"video": v} for v in videos]


def plan_jobs(entries: list[dict], out_dir: str, default_outline: str | None,
              to_argv: Callable[[dict], list[str]]) -> list[FarmJob]:
    """One :class:`FarmJob` per entry: its folder ``out_dir/<stem>`` (unique; an entry's own
    ``out`` wins), its outline (the entry's, the one beside its video, or ``default_outline``) and
    the command line ``to_argv`` makes of the entry's options."""
    stems = [os.path.splitext(os.path.basename(str(e.get("video") or f"generated-{i}")))[0] or f"job-{i}"
             for i, e in enumerate(entries)]
    jobs = []
    for name, e in zip(unique_names(stems), entries):
        e = dict(e)
        video = e.get("video")
        if video is not None and "outline" not in e:
            outline = outline_for(str(video), default_outline)
            if outline is not None:
                e["outline"] = outline
        e.setdefault("out", os.path.join(out_dir, name))
        jobs.append(FarmJob(name, None if video is None else str(video), e.get("outline"), str(e["out"]), to_argv(e)))
    return jobs
