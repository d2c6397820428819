"""Checks that ``poll()`` and the panel's ``draw()`` run at every redraw: whether a path typed in
the panel names an existing file (cached per path, so a redraw costs no disk access), and a poll
that says why it refuses (Blender shows the message as the greyed-out button's tooltip, and a
script calling the operator gets it in the RuntimeError)."""
from __future__ import annotations

import os
import time

import bpy

#: seconds a path's existence is trusted before it is checked again (a file saved meanwhile shows up)
RECHECK_S = 1.0

_EXISTS: dict[tuple[str, bool], tuple[float, bool]] = {}


def full_path(path: str) -> str:
    """``path`` as typed in the panel made absolute (``//`` is the .blend's folder)."""
    return bpy.path.abspath(path) if path else ""


def exists(path: str, folder: bool = False) -> bool:
    """True if the panel path ``path`` names an existing file (``folder``: directory); cached per
    path for :data:`RECHECK_S`. An empty path is False."""
    full = full_path(path)
    if not full:
        return False
    key = (full, folder)
    now = time.monotonic()
    hit = _EXISTS.get(key)
    if hit is None or now - hit[0] > RECHECK_S:
        if len(_EXISTS) > 256:
            _EXISTS.clear()
        hit = (now, os.path.isdir(full) if folder else os.path.isfile(full))
        _EXISTS[key] = hit
    return hit[1]


def forget(path: str = "") -> None:
    """Drop the cached answer for ``path`` (all paths: ``""``), e.g. when the field was just edited."""
    if not path:
        _EXISTS.clear()
        return
    full = full_path(path)
    for key in [k for k in _EXISTS if k[0] == full]:
        del _EXISTS[key]


def refuse(cls, message: str) -> bool:
    """For ``poll``: set ``message`` (why the button is disabled, and how to enable it) as the
    operator's poll message (Blender 3.0+), and return False."""
    if hasattr(cls, "poll_message_set"):
        cls.poll_message_set(message)
    return False


def missing_file(path: str, what: str, where: str) -> str | None:
    """The poll message for a file setting ``what`` (e.g. "video") found in panel ``where``: none
    chosen, or not found; None if it exists."""
    if not path:
        return f"no {what} chosen; pick one in the {where} panel"
    if not exists(path):
        return f"{what} '{full_path(path)}' does not exist; check the path in the {where} panel"
    return None
