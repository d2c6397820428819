"""The scene's frame rate and frame range for an animated tree: frame ``t`` of the tree (0-based)
is scene frame ``t + 1``."""
from __future__ import annotations

import math


def set_scene_timing(scene, fps: float, n_frames: int) -> None:
    """Scene frame rate ``fps`` (int ``render.fps`` + ``fps_base`` for fractional rates, e.g.
    29.97 → 30 / 1.001) and frame range ``1..n_frames``."""
    whole = round(fps)
    if abs(whole - fps) < 1e-6 * fps and whole >= 1:
        scene.render.fps, scene.render.fps_base = int(whole), 1.0
    else:
        up = max(1, math.ceil(fps))
        scene.render.fps, scene.render.fps_base = up, up / fps
    set_frame_range(scene, 1, n_frames)


def restore_scene_timing(scene, fps, fps_base, start, end, current) -> None:
    scene.render.fps, scene.render.fps_base = fps, fps_base
    set_frame_range(scene, start, end)
    scene.frame_current = current


def set_frame_range(scene, start: int, end: int) -> None:
    """Set the scene's frame range. Blender keeps start <= end on every assignment, so assign in
    an order that never crosses the current range."""
    if start > scene.frame_end:
        scene.frame_end, scene.frame_start = end, start
    else:
        scene.frame_start, scene.frame_end = start, end
