"""Cache of the expensive stages (tracks + bark statistics, hierarchy) per video and settings.

Re-running with only skeleton/3D/motion settings changed skips tracking. One ``.npz`` per key
(arrays + JSON, no pickle), written atomically; a corrupt or foreign file is ignored and rebuilt.
The key covers the video (path, size, modification time), the outline, the frame range, the
scale and every tracking/hierarchy parameter.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os

import numpy as np

from ..fileio import atomic_savez
from .appearance import AppearanceMaps
from .dense_flow import AnchoredFlow
from .hierarchy import Hierarchy
from .tracks import Tracks

VERSION = 3   # 2: tracks born after frame 1 (re-detection); 3: the dense flow from frame 1


def stage_key(video: str, outline_mask: np.ndarray, start: int, stop: int, scale: float,
              track_params, levels: int) -> str:
    """Hex digest identifying the tracking + hierarchy inputs."""
    st = os.stat(video)
    h = hashlib.sha256()
    h.update(json.dumps({"v": VERSION, "video": os.path.abspath(video), "size": st.st_size,
                         "mtime": st.st_mtime_ns, "range": [start, stop], "scale": scale, "levels": levels,
                         "track": dataclasses.asdict(track_params)}, sort_keys=True).encode())
    h.update(np.packbits(outline_mask).tobytes())
    h.update(str(outline_mask.shape).encode())
    return h.hexdigest()[:24]


def save(folder: str, key: str, tracks: Tracks, maps: AppearanceMaps, hier: Hierarchy) -> str:
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, f"stages-{key}.npz")
    sizes = np.array([len(m) for m in hier.members], np.int64)
    meta = {"version": VERSION, "fps": tracks.fps, "start": tracks.start, "size": list(tracks.size),
            "warnings": tracks.warnings, "factor": maps.factor}
    times = tracks.times if tracks.times is not None else np.arange(tracks.n_frames) / tracks.fps
    fl = tracks.flow
    flow = {} if fl is None else {"flow_frames": fl.frames, "flow_disp": fl.disp, "flow_err": fl.err,
                                  "flow_origin": fl.origin, "flow_step": np.asarray(fl.step, np.float64)}
    atomic_savez(path, points=tracks.points, valid=tracks.valid, camera=tracks.camera, times=times, **flow,
                 intensity=tracks.intensity, mean=maps.mean, std=maps.std, dark=maps.dark, mask=maps.mask,
                 first=maps.first, parent=hier.parent, level=hier.level, member_sizes=sizes,
                 members=np.concatenate(hier.members).astype(np.int64) if len(sizes) else np.zeros(0, np.int64),
                 meta_json=np.array(json.dumps(meta)))
    return path


def load(folder: str, key: str) -> tuple[Tracks, AppearanceMaps, Hierarchy] | None:
    """The cached stages for ``key``, or None (missing, unreadable or from another version)."""
    path = os.path.join(folder, f"stages-{key}.npz")
    if not os.path.isfile(path):
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta_json"]))
            if meta.get("version") != VERSION:
                return None
            flow = (AnchoredFlow(z["flow_frames"], z["flow_disp"], z["flow_err"], z["flow_origin"], z["flow_step"])
                    if "flow_frames" in z.files else None)
            tracks = Tracks(z["points"], z["valid"], z["camera"], z["intensity"], float(meta["fps"]),
                            int(meta["start"]), tuple(meta["size"]), list(meta["warnings"]), z["times"], flow)
            maps = AppearanceMaps(z["mean"], z["std"], z["dark"], z["mask"], z["first"], float(meta["factor"]))
            members = np.split(z["members"], np.cumsum(z["member_sizes"])[:-1])
            hier = Hierarchy(z["parent"], z["level"], list(members))
        return tracks, maps, hier
    except (OSError, KeyError, ValueError, json.JSONDecodeError):
        return None
