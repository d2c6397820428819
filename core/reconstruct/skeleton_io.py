"""The moving 2D skeleton as a file: ``skeleton.npz`` (``parents (N,)``, ``nodes2d (F, N, 2)`` px,
``level (N,)``, ``fps`` and JSON metadata), written atomically, read without pickle.
"""
from __future__ import annotations

import json
import os

import numpy as np

from ..fileio import atomic_savez
from .skeleton2d import Skeleton2D

FORMAT_VERSION = 1


def skeleton_arrays(skel: Skeleton2D, meta: dict | None = None) -> dict:
    """Arrays of a skeleton file: parents, nodes2d, level, fps, times (F,) s, confidence (F, N)
    (where measured), meta_json."""
    info = {"format": "tree_from_video.skeleton2d", "version": FORMAT_VERSION, "kind": skel.kind,
            "warnings": list(skel.warnings), "hidden_trunk": bool(skel.hidden_trunk),
            "limbs_seen": bool(skel.limbs_seen),
            **({"trunk_width_px": float(skel.trunk_width_px)} if np.isfinite(skel.trunk_width_px) else {}),
            **(meta or {})}
    return dict(parents=skel.parents.astype(np.int32), nodes2d=skel.nodes2d.astype(np.float32),
                level=skel.level.astype(np.int32), fps=np.float64(skel.fps), times=frame_times_of(skel),
                meta_json=np.array(json.dumps(info)),
                **({} if skel.confidence is None else {"confidence": skel.confidence.astype(np.float32)}))


def frame_times_of(skel: Skeleton2D) -> np.ndarray:
    """``(F,)`` seconds from the first frame: the skeleton's timestamps or ``index / fps``."""
    if skel.times is not None:
        return np.asarray(skel.times, np.float64)
    return np.arange(skel.nodes2d.shape[0]) / float(skel.fps)


def save_skeleton(path: str | os.PathLike, skel: Skeleton2D, meta: dict | None = None) -> None:
    """Write ``skel`` to ``path`` (.npz) atomically."""
    atomic_savez(path, **skeleton_arrays(skel, meta))


def load_skeleton(path: str | os.PathLike) -> tuple[Skeleton2D, dict]:
    """Read a skeleton file written by :func:`save_skeleton`; returns (skeleton, metadata)."""
    with np.load(os.fspath(path), allow_pickle=False) as z:
        meta = json.loads(str(z["meta_json"])) if "meta_json" in z else {}
        skel = Skeleton2D(z["parents"].astype(np.int32), z["nodes2d"].astype(np.float32),
                          z["level"].astype(np.int32), float(z["fps"]), meta.get("kind", "traced"),
                          list(meta.get("warnings", [])),
                          z["confidence"].astype(np.float32) if "confidence" in z else None,
                          z["times"].astype(np.float64) if "times" in z else None,
                          bool(meta.get("hidden_trunk", False)), bool(meta.get("limbs_seen", True)),
                          float(meta.get("trunk_width_px", np.nan)))
    return skel, meta
