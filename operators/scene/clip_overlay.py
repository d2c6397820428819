"""Tracks and the 2D skeleton drawn over the video in the Movie Clip editor (gpu draw handler).

What to draw — the per-frame image positions of the tracks and of the 2D skeleton — is kept in
the .blend with what made it: a reconstructed tree's collection (Reconstruct) or the scene
(Track & Preview: its last preview; a clip shown nowhere would not be saved), as the ID property
:data:`KEY` (an uncompressed ``.npz``, so a saved and reopened file draws the same). On a clip
the handler draws the newest overlay made from that clip's video, at the clip's current frame.
In the clip editor, ``region.view2d`` maps normalized frame coordinates (0..1, y up) to region
pixels, so the drawing follows the user's zoom and pan.
A persistent ``load_post`` handler drops what was decoded from the previous file and makes sure
the draw handler is there; both handlers are removed on unregister.
"""
from __future__ import annotations

import io
import os
import time

import bpy
import numpy as np
from bpy.app.handlers import persistent

#: the ID property (on a tree's collection or a scene) that holds an overlay: {"video", "made", "npz"}
KEY = "_tree_from_video_overlay"

_handle = None
_decoded: dict = {}       # (session_uid, made) -> overlay arrays, decoded once per file and ID


def _norm(path: str) -> str:
    return os.path.normcase(os.path.normpath(os.path.abspath(bpy.path.abspath(path))))


def overlay_arrays(res) -> dict:
    """What to draw from a pipeline result: the live tracks of every frame, ``track_xy (V, 2)``
    float32 pixels of the video at processing ``scale``, frame t's being rows ``track_start[t]``
    to ``track_start[t + 1]`` (``(F + 1,)``: only live tracks are kept, 8 bytes each — a dense
    (F, P, 2) array of every column was 96 KB a frame for a 1080p clip's 12,000 columns), and
    ``nodes (F, N, 2)``, skeleton ``edges (E, 2)``, frame ``size`` (w, h) of the full video,
    ``scale``, first frame ``start``, the nodes' ``confidence (F, N)`` and ``foreground (2K, 2)``
    float32 px, the outline of frame 1's foreground as segment endpoints in pairs (drawn on the
    first frame)."""
    from ...core.reconstruct.foreground import contour_segments
    from ...core.reconstruct.overlay import to_image
    tr, sk = res.tracks, res.skeleton
    valid = np.asarray(tr.valid, bool)
    xy = [to_image(tr.points[t][valid[t]].astype(np.float64), tr.camera[t]) for t in range(tr.n_frames)]
    start = np.concatenate([[0], np.cumsum([len(p) for p in xy])]).astype(np.int64)
    nodes = np.stack([to_image(sk.nodes2d[t].astype(np.float64), tr.camera[t]) for t in range(tr.n_frames)])
    conf = sk.confidence if sk.confidence is not None else np.ones(sk.nodes2d.shape[:2], np.float32)
    return dict(size=np.array([res.info.width / res.info.scale, res.info.height / res.info.scale], np.float64),
                scale=np.float64(res.info.scale), start=np.int64(res.start),
                track_xy=np.concatenate(xy).astype(np.float32).reshape(-1, 2), track_start=start,
                nodes=nodes.astype(np.float32), edges=np.asarray(sk.edges(), np.int32),
                confidence=np.asarray(conf, np.float32),
                foreground=(contour_segments(res.foreground.mask) if getattr(res, "foreground", None) is not None
                            else np.zeros((0, 2), np.float32)))


def frame_tracks(data: dict, t: int) -> np.ndarray:
    """Row ``t``'s live track points ``(P_t, 2)`` of overlay arrays, whether kept as
    :func:`overlay_arrays` keeps them or, in files saved before, as a dense ``tracks (F, P, 2)``
    with NaN for the tracks not live."""
    if "track_xy" in data:
        a, b = data["track_start"][t], data["track_start"][t + 1]
        return data["track_xy"][a:b]
    tracks = data["tracks"][t]
    return tracks[np.isfinite(tracks).all(axis=1)]


def store(res, owner) -> None:
    """Keep the overlay of the pipeline result ``res`` in the ID ``owner`` (the tree's collection or
    the scene), replacing the one it had; the newest overlay of a video is the one drawn."""
    buf = io.BytesIO()
    np.savez(buf, **overlay_arrays(res))
    owner[KEY] = {"video": os.path.abspath(res.info.path), "made": time.time(), "npz": buf.getvalue()}


def owners(video: str | None = None) -> list:
    """The collections and scenes of this file that hold an overlay (of ``video`` if given), newest first."""
    want = _norm(video) if video else None
    found = []
    for ids in (bpy.data.collections, bpy.data.scenes):
        for id_ in ids:
            group = id_.get(KEY)
            if group is not None and (want is None or _norm(str(group["video"])) == want):
                found.append((float(group["made"]), id_))
    return [id_ for _, id_ in sorted(found, key=lambda m: -m[0])]


def overlay_of(owner) -> dict:
    """The overlay arrays kept in ``owner`` (decoded once)."""
    group = owner[KEY]
    key = (owner.session_uid, float(group["made"]))
    if key not in _decoded:
        with np.load(io.BytesIO(bytes(group["npz"])), allow_pickle=False) as z:
            _decoded[key] = {k: z[k] for k in z.files}
    return _decoded[key]


def clear() -> None:
    _decoded.clear()


def _frame_data(clip_path: str, clip_frame: int):
    """(overlay arrays, row t, normalizer) for the clip's ``clip_frame`` (1-based), or None."""
    found = owners(clip_path) if clip_path else []
    if not found:
        return None
    data = overlay_of(found[0])
    t = clip_frame - 1 - int(data["start"])
    if not 0 <= t < len(data["nodes"]):
        return None
    w, h = data["size"]
    s = float(data["scale"])

    def norm(p):
        p = p / s
        return np.stack([p[:, 0] / w, 1.0 - p[:, 1] / h], axis=1)
    return data, t, norm


def frame_confidence(clip_path: str, clip_frame: int):
    """(node positions (N, 2) in normalized frame coordinates, y up; their motion confidence (N,))
    for the clip's ``clip_frame`` from the newest overlay of its video, or None (also for an
    overlay kept before confidence was measured)."""
    got = _frame_data(clip_path, clip_frame)
    if got is None or "confidence" not in got[0]:
        return None
    data, t, norm = got
    return norm(data["nodes"][t]), data["confidence"][t]


def frame_geometry(clip_path: str, clip_frame: int):
    """(track points (P, 2), skeleton segment endpoints (2E, 2)) in normalized frame coordinates
    (y up) for the clip's ``clip_frame`` (1-based) from the newest overlay of the clip's video,
    or None when there is nothing to draw."""
    got = _frame_data(clip_path, clip_frame)
    if got is None:
        return None
    data, t, norm = got
    pts = norm(frame_tracks(data, t))
    seg = norm(data["nodes"][t][data["edges"].reshape(-1)])
    return pts, seg


def frame_foreground(clip_path: str, clip_frame: int):
    """The outline of frame 1's foreground as segment endpoints ``(2K, 2)`` in normalized frame
    coordinates (y up) when ``clip_frame`` is the overlay's first frame, else None (also for an
    overlay kept before the foreground was measured)."""
    got = _frame_data(clip_path, clip_frame)
    if got is None or got[1] != 0 or "foreground" not in got[0] or not len(got[0]["foreground"]):
        return None
    return got[2](np.asarray(got[0]["foreground"], np.float64))


def _draw():
    import gpu
    from gpu_extras.batch import batch_for_shader
    space = bpy.context.space_data
    clip = getattr(space, "clip", None)
    if clip is None:
        return
    geo = frame_geometry(bpy.path.abspath(clip.filepath), space.clip_user.frame_current)
    if geo is None:
        return
    pts, seg = geo
    conf = frame_confidence(bpy.path.abspath(clip.filepath), space.clip_user.frame_current)
    v2d = bpy.context.region.view2d
    o = np.array(v2d.view_to_region(0.0, 0.0, clip=False), float)
    one = np.array(v2d.view_to_region(1.0, 1.0, clip=False), float)
    scale = one - o
    shader = gpu.shader.from_builtin("UNIFORM_COLOR")
    gpu.state.blend_set("ALPHA")
    gpu.state.point_size_set(3.0)
    shader.bind()
    if len(pts):
        shader.uniform_float("color", (0.3, 1.0, 0.3, 0.9))
        batch_for_shader(shader, "POINTS", {"pos": (o + pts * scale).tolist()}).draw(shader)
    if len(seg):
        gpu.state.line_width_set(2.0)
        shader.uniform_float("color", (1.0, 0.55, 0.1, 1.0))
        batch_for_shader(shader, "LINES", {"pos": (o + seg * scale).tolist()}).draw(shader)
        gpu.state.line_width_set(1.0)
    fg = frame_foreground(bpy.path.abspath(clip.filepath), space.clip_user.frame_current)
    if fg is not None:                       # frame 1's foreground: the tree's pixels the leaves fill
        shader.uniform_float("color", (0.0, 1.0, 1.0, 0.9))
        batch_for_shader(shader, "LINES", {"pos": (o + fg * scale).tolist()}).draw(shader)
    if conf is not None:                     # nodes by motion confidence: red poorly measured, yellow, green
        from ...core.reconstruct.overlay import CONFIDENCE_COLOURS, confidence_bins
        nodes, c = conf
        bins = confidence_bins(c)
        gpu.state.point_size_set(6.0)
        for k, (b, g, r) in enumerate(CONFIDENCE_COLOURS):
            sel = nodes[bins == k]
            if len(sel):
                shader.uniform_float("color", (r / 255.0, g / 255.0, b / 255.0, 1.0))
                batch_for_shader(shader, "POINTS", {"pos": (o + sel * scale).tolist()}).draw(shader)
    gpu.state.point_size_set(1.0)
    gpu.state.blend_set("NONE")


def _add_draw_handler() -> None:
    global _handle
    if _handle is None and not bpy.app.background:
        _handle = bpy.types.SpaceClipEditor.draw_handler_add(_draw, (), "WINDOW", "POST_PIXEL")


@persistent
def on_load_post(*_args) -> None:
    """After a file is opened: forget what was decoded from the previous one; (re)add the draw
    handler, so the overlays kept in the file are drawn again."""
    clear()
    _add_draw_handler()


def register() -> None:
    _add_draw_handler()
    if on_load_post not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(on_load_post)


def unregister() -> None:
    global _handle
    for fn in [f for f in bpy.app.handlers.load_post if getattr(f, "__name__", "") == "on_load_post"
               and getattr(f, "__module__", "") == __name__]:
        bpy.app.handlers.load_post.remove(fn)
    if _handle is not None:
        bpy.types.SpaceClipEditor.draw_handler_remove(_handle, "WINDOW")
        _handle = None
    clear()
