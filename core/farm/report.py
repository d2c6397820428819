"""``report.json`` and ``job.log``: what one batch job did, for the user and for a farm.

The report (schema: ``docs/report.schema.json``) holds the job's status (``running`` while it
works, so a killed run leaves a folder that says so; then ``ok``, ``bad_input``, ``error`` or
``cancelled``), the one-line message of a failure, the command and its settings (with their
hash), the input's size and content hash, the video read (frames, fps, the time base), seconds
per stage (the progress callback's stages, wall clock), counts (tracks, nodes, bones, leaf
clusters, triangles), warnings, the files written with their sizes, the versions of everything
that computed it and the peak memory. Both files are written atomically (:mod:`..fileio`).
"""
from __future__ import annotations

import os
import platform
import resource
import sys
import time
from dataclasses import dataclass, field
from typing import Any

from ..fileio import atomic_write_bytes, atomic_write_json, read_json
from ..progress import ProgressFn

REPORT, LOG = "report.json", "job.log"
SCHEMA = "tree_from_video/report/1"
STATUSES = ("running", "ok", "bad_input", "error", "cancelled")


def versions(package: str) -> dict[str, str | None]:
    """The versions that computed a job: the package's, Python's, numpy's, OpenCV's, SciPy's and
    Blender's (None outside Blender; bpy is only looked up when it is already loaded)."""
    import cv2
    import numpy
    import scipy
    bpy = sys.modules.get("bpy")
    app = getattr(bpy, "app", None)
    return {"tree_from_video": package, "python": platform.python_version(), "numpy": numpy.__version__,
            "opencv": cv2.__version__, "scipy": scipy.__version__,
            "blender": getattr(app, "version_string", None) if app is not None else None}


def peak_rss_mb() -> float:
    """The process's peak resident memory so far, MB (Linux reports KB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def read_report(folder: str) -> dict | None:
    """The report a folder holds, or None (none, or not readable: then it is no proof of a finished
    job)."""
    path = os.path.join(folder, REPORT)
    if not os.path.isfile(path):
        return None
    try:
        doc = read_json(path, REPORT, "")
    except Exception:
        return None
    return doc if isinstance(doc, dict) else None


@dataclass
class JobRecord:
    """What one job did, filled as it runs; :meth:`write` puts it in its folder. ``stages``
    seconds per progress stage; ``counts`` summed over the job's trees; ``log`` the job's lines."""

    command: list[str]
    settings: dict[str, Any]
    settings_sha256: str
    package: str
    input: dict | None = None
    status: str = "running"
    message: str | None = None
    video: dict | None = None
    stages: dict[str, float] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    outputs: list[dict] = field(default_factory=list)
    log: list[str] = field(default_factory=list)
    started: float = field(default_factory=time.time)
    _t0: float = field(default_factory=time.monotonic)
    _stage: str | None = None
    _stage_t: float = 0.0

    def timed(self, progress: ProgressFn | None) -> ProgressFn:
        """``progress`` wrapped so the time between a stage's first report and the next stage's
        adds to ``stages``."""
        def cb(stage: str, fraction: float):
            now = time.monotonic()
            if stage != self._stage:
                self._close_stage(now)
                self._stage, self._stage_t = stage, now
            return None if progress is None else progress(stage, fraction)
        return cb

    def _close_stage(self, now: float) -> None:
        if self._stage is not None:
            self.stages[self._stage] = round(self.stages.get(self._stage, 0.0) + now - self._stage_t, 3)
            self._stage = None

    def add(self, **counts: int) -> None:
        """Add to the counts (``tracks=1661, nodes=180``…)."""
        for k, v in counts.items():
            self.counts[k] = int(self.counts.get(k, 0)) + int(v)

    def warn(self, message: str) -> None:
        if message not in self.warnings:
            self.warnings.append(message)

    def finish(self, status: str, message: str | None, folder: str | None) -> None:
        """Set the final status and list the files the job wrote under ``folder`` (those changed
        since it started; the report and log excepted; None: a job that wrote no folder, the
        panel's, whose tree is in the scene)."""
        assert status in STATUSES, status
        self._close_stage(time.monotonic())
        self.status, self.message = status, message
        self.outputs = []
        for root, _, files in os.walk(folder) if folder else ():
            for name in sorted(files):
                path = os.path.join(root, name)
                rel = os.path.relpath(path, folder).replace(os.sep, "/")
                if rel in (REPORT, LOG) or name.startswith(".tmp-"):
                    continue
                st = os.stat(path)
                if st.st_mtime >= self.started - 1.0:
                    self.outputs.append({"path": rel, "bytes": int(st.st_size)})
        self.outputs.sort(key=lambda o: o["path"])

    def to_json(self) -> dict:
        return {"schema": SCHEMA, "status": self.status, "message": self.message, "command": list(self.command),
                "settings": self.settings, "settings_sha256": self.settings_sha256, "input": self.input,
                "video": self.video, "stages": dict(self.stages), "counts": dict(self.counts),
                "warnings": list(self.warnings), "outputs": list(self.outputs),
                "versions": versions(self.package), "peak_rss_mb": round(peak_rss_mb(), 1),
                "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(self.started)),
                "seconds": round(time.monotonic() - self._t0, 3)}

    def write(self, folder: str) -> None:
        """``folder/report.json`` and ``folder/job.log``, atomically."""
        atomic_write_json(os.path.join(folder, REPORT), self.to_json())
        atomic_write_bytes(os.path.join(folder, LOG), "".join(self.log).encode("utf-8"))
