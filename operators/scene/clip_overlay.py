"""Tracks and the 2D skeleton drawn over the video in the Movie Clip editor (gpu draw handler).

After a preview or a reconstruction the per-frame image positions are kept in memory (one video
at a time); the handler draws them on the clip whose file is that video, at the clip's current
frame. In the clip editor, ``region.view2d`` maps normalized frame coordinates (0..1, y up) to
region pixels, so the drawing follows the user's zoom and pan. The handler is removed on unregister.
"""
from __future__ import annotations

import os

import bpy
import numpy as np

_handle = None
_data: dict = {}


def store(res) -> None:
    """Keep what to draw from a pipeline result: image-space tracks and skeleton per frame."""
    from ...core.reconstruct.overlay import to_image
    tr, sk = res.tracks, res.skeleton
    pts = np.stack([to_image(tr.points[t].astype(np.float64), tr.camera[t]) for t in range(tr.n_frames)])
    nodes = np.stack([to_image(sk.nodes2d[t].astype(np.float64), tr.camera[t]) for t in range(tr.n_frames)])
    _data.clear()
    _data.update(video=os.path.abspath(res.info.path), size=(res.info.width / res.info.scale,
                                                              res.info.height / res.info.scale),
                 scale=res.info.scale, start=res.start, tracks=pts.astype(np.float32), valid=tr.valid,
                 nodes=nodes.astype(np.float32), edges=sk.edges())


def clear() -> None:
    _data.clear()


def frame_geometry(clip_path: str, clip_frame: int):
    """(track points (P, 2), skeleton segment endpoints (2E, 2)) in normalized frame coordinates
    (y up) for the clip's ``clip_frame`` (1-based), or None when there is nothing to draw."""
    if not _data or os.path.abspath(clip_path) != _data["video"]:
        return None
    t = clip_frame - 1 - _data["start"]
    if not 0 <= t < len(_data["tracks"]):
        return None
    w, h = _data["size"]
    s = _data["scale"]

    def norm(p):
        p = p / s
        return np.stack([p[:, 0] / w, 1.0 - p[:, 1] / h], axis=1)
    pts = norm(_data["tracks"][t][_data["valid"][t]])
    e = _data["edges"]
    seg = norm(_data["nodes"][t][e.reshape(-1)])
    return pts, seg


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
    gpu.state.point_size_set(1.0)
    gpu.state.blend_set("NONE")


def register() -> None:
    global _handle
    if _handle is None and not bpy.app.background:
        _handle = bpy.types.SpaceClipEditor.draw_handler_add(_draw, (), "WINDOW", "POST_PIXEL")


def unregister() -> None:
    global _handle
    if _handle is not None:
        bpy.types.SpaceClipEditor.draw_handler_remove(_handle, "WINDOW")
        _handle = None
    clear()
