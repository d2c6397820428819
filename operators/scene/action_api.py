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


def rig_action(rig):
    """The action ``rig`` plays: its active action, else its first NLA strip's (an instance);
    None for an unanimated rig."""
    ad = getattr(rig, "animation_data", None)
    if ad is None:
        return None
    if ad.action is not None:
        return ad.action
    for track in ad.nla_tracks:
        for strip in track.strips:
            if strip.action is not None:
                return strip.action
    return None


_ENUMS: dict = {}


def _enum(struct, prop: str, name: str) -> int:
    key = (struct.__name__, prop, name)
    if key not in _ENUMS:
        _ENUMS[key] = struct.bl_rna.properties[prop].enum_items[name].value
    return _ENUMS[key]


def write_keys(fcurve: bpy.types.FCurve, frames: np.ndarray, values: np.ndarray,
               handles: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Add one key per ``(frames[i], values[i])`` to ``fcurve``, in bulk: LINEAR, or with
    ``handles`` (left, right: ``(F, 2)`` (frame, value) each) BEZIER keys with those FREE handles
    (:func:`core.keys.handles`).

    ``frames (F,)`` scene frames, increasing; ``values (F,)`` in the property's unit.
    Uses ``keyframe_points.add`` + ``foreach_set`` (no per-key Python), then ``fcurve.update()``."""
    frames = np.asarray(frames, np.float32).ravel()
    values = np.asarray(values, np.float32).ravel()
    if frames.shape != values.shape:
        raise ValueError(f"frames {frames.shape} and values {values.shape} differ in length")
    kind = _enum(bpy.types.Keyframe, "interpolation", "LINEAR" if handles is None else "BEZIER")
    n = len(frames)
    points = fcurve.keyframe_points
    start = len(points)
    points.add(n)
    co = np.empty((start + n, 2), np.float32)
    interp = np.full(start + n, kind, np.int32)
    if start:                                   # keep the keys that were there
        points.foreach_get("co", co.ravel())
        points.foreach_get("interpolation", interp)
        interp[start:] = kind
    co[start:, 0] = frames
    co[start:, 1] = values
    points.foreach_set("co", co.ravel())
    points.foreach_set("interpolation", interp)
    if handles is not None:
        free = _enum(bpy.types.Keyframe, "handle_left_type", "FREE")
        for side, h in zip(("left", "right"), handles):
            kinds = np.empty(start + n, np.int32)
            points.foreach_get(f"handle_{side}_type", kinds)
            kinds[start:] = free
            points.foreach_set(f"handle_{side}_type", kinds)
            xy = np.empty((start + n, 2), np.float32)
            points.foreach_get(f"handle_{side}", xy.ravel())
            xy[start:] = np.asarray(h, np.float32).reshape(n, 2)
            points.foreach_set(f"handle_{side}", xy.ravel())
    fcurve.update()


def write_samples(fcurve: bpy.types.FCurve, first: int, values: np.ndarray) -> None:
    """Store ``values (F,)`` as the F-curve's baked samples on the scene frames ``first ..
    first + F - 1`` (``FCurve.convert_to_samples``: one float pair per frame, a quarter of a key's
    bytes, played linearly between frames; the Graph Editor's *Unbake* turns them back into keys)."""
    values = np.asarray(values, np.float32).ravel()
    write_keys(fcurve, np.arange(first, first + len(values), dtype=np.float32), values)
    fcurve.convert_to_samples(int(first), int(first) + len(values))
