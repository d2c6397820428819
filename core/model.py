"""Saving and loading stage outputs as ``.npz`` (+ JSON metadata inside it); never pickle.

Files are written atomically: to a temporary name in the same folder, then renamed.
"""
from __future__ import annotations

import json
import os
import tempfile

import numpy as np

from .skeleton2d import Skeleton2D

FORMAT_VERSION = 1


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


def skeleton_arrays(skel: Skeleton2D, meta: dict | None = None) -> dict:
    """Arrays of a skeleton file: parents, nodes2d, level, fps, meta_json."""
    info = {"format": "tree_from_video.skeleton2d", "version": FORMAT_VERSION, "kind": skel.kind,
            "warnings": list(skel.warnings), **(meta or {})}
    return dict(parents=skel.parents.astype(np.int32), nodes2d=skel.nodes2d.astype(np.float32),
                level=skel.level.astype(np.int32), fps=np.float64(skel.fps),
                meta_json=np.array(json.dumps(info)))


def save_skeleton(path: str | os.PathLike, skel: Skeleton2D, meta: dict | None = None) -> None:
    """Write ``skel`` to ``path`` (.npz) atomically."""
    atomic_savez(path, **skeleton_arrays(skel, meta))


def load_skeleton(path: str | os.PathLike) -> tuple[Skeleton2D, dict]:
    """Read a skeleton file written by :func:`save_skeleton`; returns (skeleton, metadata)."""
    with np.load(os.fspath(path), allow_pickle=False) as z:
        meta = json.loads(str(z["meta_json"])) if "meta_json" in z else {}
        skel = Skeleton2D(z["parents"].astype(np.int32), z["nodes2d"].astype(np.float32),
                          z["level"].astype(np.int32), float(z["fps"]), meta.get("kind", "traced"),
                          list(meta.get("warnings", [])))
    return skel, meta
