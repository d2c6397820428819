"""The record of a reconstruction run from the panel (issue 34): the same ``report.json`` a batch
job leaves (:class:`core.farm.report.JobRecord`: settings, the input's size and content hash, the
video read, seconds per stage, counts, warnings, versions, peak memory), kept with each tree it
built and written beside each file the tree is exported to as ``<file>.report.json``
(``Oak.glb.report.json``: one per file, so a GLB and an FBX of the tree each have theirs)."""
from __future__ import annotations

import hashlib
import json

import numpy as np

from ... import __version__
from ...core.farm import identity
from ...core.farm.report import JobRecord

#: custom property of a tree's collection: its report, JSON text
KEY = "_tree_video_report"
#: what the report's file name adds to the exported file's
SUFFIX = ".report.json"


def panel_record(settings: dict, video: str) -> JobRecord:
    """A running record of a panel reconstruction with ``settings`` (its job's,
    :func:`core.jobs.settings_doc`: the batch options' names, so a report is a job file's options);
    its input is set by :func:`set_input` in the worker (hashing takes time)."""
    return JobRecord(["Blender: Tree from Video › Reconstruct", video], settings, identity.settings_hash(settings),
                     __version__)


def set_input(record: JobRecord, video: str, outline) -> None:
    """The record's input: the video's size and SHA-256 and the outline's (a file's hash, or the
    hash of a drawn polygon's float64 pixels, named ``drawn``; ``auto`` named)."""
    if isinstance(outline, str):
        record.input = identity.input_identity(video, outline)
        return
    record.input = identity.input_identity(video, None)
    if record.input is not None:
        polys = outline if isinstance(outline, list) else [outline]
        h = hashlib.sha256()
        for poly in polys:
            h.update(np.ascontiguousarray(poly, np.float64).tobytes())
        record.input.update(outline="drawn", outline_sha256=h.hexdigest())


def record_results(record: JobRecord, pairs) -> None:
    """The video read, the counts and the warnings of the reconstructed ``pairs`` ``[(Result, Tree3D)]``."""
    res = pairs[0][0]
    info = res.info
    record.video = {"width": info.width, "height": info.height, "fps": float(info.fps),
                    "frames": [int(res.start), int(res.stop)],
                    "time_base": "index / fps" if res.tracks.times is None else "frame timestamps"}
    for r, tree in pairs:
        record.add(trees=1, tracks=r.tracks.n_tracks, nodes=tree.n_nodes,
                   leaf_clusters=tree.leaves.count if tree.leaves is not None else 0)
        for w in r.warnings:
            record.warn(w)


def keep(coll, record: JobRecord) -> None:
    """Keep the finished ``record`` with tree ``coll``: Export writes it beside the tree's files."""
    coll[KEY] = json.dumps(record.to_json(), indent=2)


def kept(coll) -> dict | None:
    """The report kept with tree ``coll``, or None (a generated tree, or one built before reports)."""
    text = coll.get(KEY) if coll is not None else None
    return None if not text else json.loads(str(text))


def kept_files(coll, path: str) -> dict[str, bytes]:
    """``{path of the report beside the exported file path: its bytes}`` ({} without a report)."""
    doc = kept(coll)
    return {} if doc is None else {path + SUFFIX: json.dumps(doc, indent=2).encode("utf-8")}
