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


def fit_scene_timing(scene, fps: float, n_frames: int, first: bool) -> None:
    """Make the scene play a tree of ``n_frames`` frames (scene frames ``1..n_frames``).

    The first tree of a scene sets its frame rate and range (:func:`set_scene_timing`: a
    reconstruction plays at the video's rate). A tree added to a scene that already holds trees
    only grows the range to cover it (start at most 1, end at least ``n_frames``) and keeps the
    frame rate: Generate must not cut a 555-frame reconstruction's playback to its own 180."""
    if first:
        set_scene_timing(scene, fps, n_frames)
        return
    set_frame_range(scene, min(scene.frame_start, 1), max(scene.frame_end, int(n_frames)))


def scene_fps(scene) -> float:
    """The scene's frame rate in frames per second (``fps / fps_base``)."""
    return scene.render.fps / scene.render.fps_base


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
