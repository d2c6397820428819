"""Files every stage writes and reads: atomic writes (a temporary name in the same folder,
then renamed; the user's umask kept) of ``.npz`` archives (never pickle), and the small JSON
files users hand us (outlines, species), read with one clear error.
"""
from __future__ import annotations

import json
import os
import tempfile

import numpy as np

from .errors import InputError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def publish(tmp: str, path: str | os.PathLike) -> None:
    """Give the finished temporary file ``tmp`` the permissions a plain new file would have
    (``mkstemp`` makes it private) and rename it to ``path``."""
    os.chmod(tmp, 0o666 & ~_umask())
    os.replace(tmp, path)


def temp_path(path: str | os.PathLike, suffix: str) -> str:
    """A not-yet-existing hidden temporary name in ``path``'s folder (for writers that refuse to
    write over an existing file or back it up, like Blender's save)."""
    import uuid
    folder = os.path.dirname(os.path.abspath(path))
    return os.path.join(folder, f".tmp-{uuid.uuid4().hex[:12]}{suffix}")


def atomic_savez(path: str | os.PathLike, **arrays) -> None:
    """``np.savez_compressed`` to ``path`` through a temporary file in the same folder."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".npz", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        publish(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise



def read_json(path: str | os.PathLike, what: str, fix: str):
    """The parsed content of the JSON file ``path``; :class:`InputError` "``what`` is not readable
    JSON (reason); ``fix``" when it cannot be opened, decoded or parsed."""
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{what} is not readable JSON ({exc.__class__.__name__}); {fix}") from None

def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """``data`` to ``path`` through a temporary file in the same folder."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=os.path.splitext(path)[1], dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        publish(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def json_bytes(doc) -> bytes:
    """``doc`` as indented JSON, UTF-8."""
    return (json.dumps(doc, indent=1) + "\n").encode()


def atomic_write_json(path: str | os.PathLike, doc) -> None:
    """``doc`` as indented JSON (UTF-8) to ``path``, atomically."""
    atomic_write_bytes(path, json_bytes(doc))


def write_files(folder: str | os.PathLike, files: dict[str, bytes]) -> list[str]:
    """Each ``{name: bytes}`` to ``folder/name``, atomically; their paths in order."""
    paths = []
    for name, data in files.items():
        path = os.path.join(os.fspath(folder), name)
        atomic_write_bytes(path, data)
        paths.append(path)
    return paths
