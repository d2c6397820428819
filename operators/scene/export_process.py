"""Trees' exports in background Blender processes, so the user's Blender keeps drawing, showing
progress and taking Esc while the exporter works (issue 32: one tree's glTF export was one
uninterrupted 6–21 s on the main thread).

:func:`start` copies the trees' objects (with everything they use: meshes, armatures, actions,
materials, packed images) into a temporary .blend (``bpy.data.libraries.write``, ~0.1 s for a
10 MB tree) and runs ``blender -b COPY --python export_worker.py`` on it, which writes one file per
tree, in order, with the same writer (:mod:`.export`) the add-on uses in-process, and prints a line
as each is done. One process writes several trees (a Blender's start and the add-on's import,
~1.5 s, are paid once: the default 12-tree forest's GLBs 63 → 55 s); :func:`split` shares the trees
among :data:`PARALLEL` processes by size. The way a farm will run exports. Used by the panel's
export job when this Blender can start another (:func:`available`: a GUI session with its binary
at hand); scripts, tests and ``blender -b`` export in-process.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence

import bpy

from .export_worker import DONE_PREFIX, ERROR_PREFIX

#: export processes at once (one per core of the 2-core machines this was measured on)
PARALLEL = 2
#: set (to anything) to export in-process even in a GUI session
INPROCESS_ENV = "TREE_VIDEO_EXPORT_INPROCESS"
#: the add-on's folder (the package root) and the worker script
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WORKER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "export_worker.py")


def available() -> bool:
    """Whether exports can run in a background Blender: a GUI session whose binary exists (the bpy
    module and ``blender -b`` export in-process), unless :data:`INPROCESS_ENV` is set."""
    binary = bpy.app.binary_path
    return (not bpy.app.background and bool(binary) and os.path.isfile(binary)
            and not os.environ.get(INPROCESS_ENV))


def split(sizes: Sequence[float], parts: int = PARALLEL) -> list[list[int]]:
    """The indices of ``sizes`` shared among at most ``parts`` lists of about equal total size
    (largest first, each to the lightest list so far); each list in ascending index order, empty
    lists dropped."""
    bins: list[list[int]] = [[] for _ in range(max(1, min(parts, len(sizes))))]
    load = [0.0] * len(bins)
    for i in sorted(range(len(sizes)), key=lambda i: (-sizes[i], i)):
        k = load.index(min(load))
        bins[k].append(i)
        load[k] += sizes[i]
    return [sorted(b) for b in bins if b]


class ExportProcess:
    """Several trees' exports running one after another in a background Blender: :meth:`done`
    (how many are written so far), :meth:`poll` (None while it runs, else its exit code),
    :meth:`error` (the worker's message, or the last lines it printed), :meth:`kill`;
    :meth:`cleanup` removes the temporary copy (both safe to call twice)."""

    def __init__(self, fmt: str, jobs: Sequence[tuple[Sequence, str]], overwrite: bool,
                 fbx_extra: dict | None = None, games: Sequence[bool] | None = None):
        """``jobs``: (the tree's objects, the file to write) per tree, written in this order."""
        self.folder = tempfile.mkdtemp(prefix="tree_video_export_")
        blend = os.path.join(self.folder, "trees.blend")
        bpy.data.libraries.write(blend, {ob for objects, _ in jobs for ob in objects}, fake_user=True)
        args = json.dumps({"root": ROOT, "path": sys.path, "format": fmt, "overwrite": bool(overwrite),
                           "fbx_extra": dict(fbx_extra or {}),
                           "jobs": [{"objects": [ob.name for ob in objects], "out": out,
                                     "game": bool(games[k]) if games else False}
                                    for k, (objects, out) in enumerate(jobs)]})
        self.log = open(os.path.join(self.folder, "log.txt"), "w+")
        prefix, keywords = _lower_priority()
        self.proc = subprocess.Popen(
            prefix + [bpy.app.binary_path, "-b", "--factory-startup", blend, "--python-exit-code", "1",
                      "--python", WORKER, "--", args],
            stdout=self.log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, **keywords)

    def _lines(self) -> list[str]:
        self.log.flush()
        self.log.seek(0)
        return [ln.rstrip() for ln in self.log.read().splitlines() if ln.strip()]

    def done(self) -> int:
        """How many of the jobs the worker reports written (they are written in order)."""
        return len(self.seconds())

    def seconds(self) -> list[float]:
        """Each written job's export time, s, as the worker reports it (in order)."""
        return [float(ln.split()[-1]) for ln in self._lines() if ln.startswith(DONE_PREFIX)]

    def poll(self) -> int | None:
        return self.proc.poll()

    def error(self) -> str:
        """The worker's one-line message, or the last lines the process printed."""
        lines = self._lines()
        for ln in lines:
            if ln.startswith(ERROR_PREFIX):
                return ln[len(ERROR_PREFIX):]
        tail = " | ".join(lines[-3:])
        return f"the background export stopped with code {self.proc.returncode} ({tail})"

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass

    def cleanup(self) -> None:
        self.kill()
        if not self.log.closed:
            self.log.close()
        shutil.rmtree(self.folder, ignore_errors=True)


#: the background exports' niceness (POSIX): the user's Blender keeps the CPU it needs to draw while
#: :data:`PARALLEL` exports fill the cores (measured under software GL, where a viewport draw costs
#: CPU: at equal priority the Blenders' start-up held one draw back 0.5 s here and 1.5 s on a slower
#: machine; niced, 0.3 s, the exports taking the CPU the drawing leaves)
NICENESS = 10


def _lower_priority() -> tuple[list[str], dict]:
    """The command prefix and ``subprocess.Popen`` keywords that start an export below the user's
    Blender's priority: ``nice -n`` on POSIX (every thread Blender starts inherits it; no
    ``preexec_fn``, unsafe in a threaded process), ``BELOW_NORMAL_PRIORITY_CLASS`` on Windows."""
    if os.name == "nt":
        return [], {"creationflags": getattr(subprocess, "BELOW_NORMAL_PRIORITY_CLASS", 0)}
    nice = shutil.which("nice")
    return ([nice, "-n", str(NICENESS)] if nice else []), {}


def start(fmt: str, jobs: Sequence[tuple[Sequence, str]], overwrite: bool,
          fbx_extra: dict | None = None, games: Sequence[bool] | None = None) -> ExportProcess:
    """Start exporting, as ``fmt`` ("FBX", "GLB", "USD"), each job's objects to its file, one after
    another in one background Blender (``fbx_extra``: an engine preset's FBX options; ``games``: per
    job, a game tree whose GLB is packed for engines)."""
    return ExportProcess(fmt, jobs, overwrite, fbx_extra, games)
