"""A tree's export in a background Blender process, so the user's Blender keeps drawing, showing
progress and taking Esc while the exporter works (issue 32: one tree's glTF export was one
uninterrupted 6–21 s on the main thread).

:func:`start` copies the tree's objects (with everything they use: meshes, armature, actions,
materials, packed images) into a temporary .blend (``bpy.data.libraries.write``, ~0.1 s for a
10 MB tree) and runs ``blender -b COPY --python export_worker.py`` on it, which writes the file
with the same writer (:mod:`.export`) the add-on uses in-process. The way a farm will run exports.
Used by the panel's export job when this Blender can start another (:func:`available`: a GUI
session with its binary at hand); scripts, tests and ``blender -b`` export in-process.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile

import bpy

from .export_worker import ERROR_PREFIX

#: exports run at once (one per core of the 2-core machines this was measured on)
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


class ExportProcess:
    """One tree's export running in a background Blender: :meth:`poll` (None while it runs, else its
    exit code), :meth:`error` (the worker's message, or the last lines it printed), :meth:`kill`;
    :meth:`cleanup` removes the temporary copy (both safe to call twice)."""

    def __init__(self, fmt: str, objects, out: str, overwrite: bool):
        self.out = out
        self.folder = tempfile.mkdtemp(prefix="tree_video_export_")
        blend = os.path.join(self.folder, "tree.blend")
        bpy.data.libraries.write(blend, set(objects), fake_user=True)
        args = json.dumps({"root": ROOT, "path": sys.path, "format": fmt, "out": out,
                           "objects": [ob.name for ob in objects], "overwrite": bool(overwrite)})
        self.log = open(os.path.join(self.folder, "log.txt"), "w+")
        self.proc = subprocess.Popen(
            [bpy.app.binary_path, "-b", "--factory-startup", blend, "--python-exit-code", "1",
             "--python", WORKER, "--", args],
            stdout=self.log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)

    def poll(self) -> int | None:
        return self.proc.poll()

    def error(self) -> str:
        """The worker's one-line message, or the last lines the process printed."""
        self.log.flush()
        self.log.seek(0)
        lines = [ln.rstrip() for ln in self.log.read().splitlines() if ln.strip()]
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


def start(fmt: str, objects, out: str, overwrite: bool) -> ExportProcess:
    """Start exporting ``objects`` as ``fmt`` ("FBX", "GLB", "USD") to ``out`` in the background."""
    return ExportProcess(fmt, objects, out, overwrite)
