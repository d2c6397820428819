"""Actions and F-curves across Blender versions, and bulk keyframes.

Blender 4.4 introduced slotted actions (slots → layers → strips → channelbags) and 5.0 removed
``Action.fcurves``; Blender 4.2–4.3 only have ``Action.fcurves``. :func:`new_action` picks the API
by feature (``hasattr(action, "slots")``), not by version number.
"""
from __future__ import annotations

from typing import Callable, Iterator

import bpy
import numpy as np

FCurveMaker = Callable[[str, int, str], "bpy.types.FCurve"]


def new_action(obj: bpy.types.Object, name: str) -> tuple[bpy.types.Action, FCurveMaker]:
    """Create an action named ``name``, assign it to ``obj`` and return ``(action, make_fcurve)``.

    ``make_fcurve(data_path, index, group)`` adds an F-curve animating ``obj`` (``group`` is the
    channel group shown in the editors, e.g. the bone name). Slotted actions get one slot, one
    layer and one keyframe strip; legacy actions use ``action.fcurves``. The caller owns the
    action (remove it with ``bpy.data.actions.remove`` on failure)."""
    action = bpy.data.actions.new(name)
    if obj.animation_data is None:
        obj.animation_data_create()
    if hasattr(action, "slots"):                                  # Blender 4.4+ / 5.x
        slot = action.slots.new(id_type=obj.id_type, name=obj.name)
        strip = action.layers.new("Layer").strips.new(type="KEYFRAME")
        bag = strip.channelbag(slot, ensure=True)
        obj.animation_data.action = action
        obj.animation_data.action_slot = slot
        fcurves = bag.fcurves
        with_group = "group_name" in fcurves.bl_rna.functions["new"].parameters  # 5.0+ (not 4.4/4.5)

        def make_fcurve(data_path: str, index: int, group: str = "") -> bpy.types.FCurve:
            if with_group and group:
                return fcurves.new(data_path, index=index, group_name=group)
            return fcurves.new(data_path, index=index)
    else:                                                         # Blender 4.2-4.3
        obj.animation_data.action = action

        def make_fcurve(data_path: str, index: int, group: str = "") -> bpy.types.FCurve:
            return action.fcurves.new(data_path, index=index, action_group=group)
    return action, make_fcurve


def action_fcurves(action: bpy.types.Action) -> Iterator[bpy.types.FCurve]:
    """Every F-curve of ``action`` (all slots, layers and strips on slotted actions)."""
    if hasattr(action, "layers"):
        for layer in action.layers:
            for strip in layer.strips:
                for bag in getattr(strip, "channelbags", ()):
                    yield from bag.fcurves
    if not hasattr(action, "slots"):
        yield from action.fcurves


_LINEAR = None


def write_keys(fcurve: bpy.types.FCurve, frames: np.ndarray, values: np.ndarray) -> None:
    """Add one LINEAR key per ``(frames[i], values[i])`` to ``fcurve``, in bulk.

    ``frames (F,)`` scene frames, increasing; ``values (F,)`` in the property's unit.
    Uses ``keyframe_points.add`` + ``foreach_set`` (no per-key Python), then ``fcurve.update()``."""
    global _LINEAR
    if _LINEAR is None:
        _LINEAR = bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items["LINEAR"].value
    frames = np.asarray(frames, np.float32).ravel()
    values = np.asarray(values, np.float32).ravel()
    if frames.shape != values.shape:
        raise ValueError(f"frames {frames.shape} and values {values.shape} differ in length")
    n = len(frames)
    points = fcurve.keyframe_points
    start = len(points)
    points.add(n)
    co = np.empty((start + n, 2), np.float32)
    interp = np.full(start + n, _LINEAR, np.int32)
    if start:                                   # keep the keys that were there
        points.foreach_get("co", co.ravel())
        points.foreach_get("interpolation", interp)
        interp[start:] = _LINEAR
    co[start:, 0] = frames
    co[start:, 1] = values
    points.foreach_set("co", co.ravel())
    points.foreach_set("interpolation", interp)
    fcurve.update()
