"""The outline from an annotation stroke drawn over the clip with the Annotate tool.

Blender 4.x keeps a clip's annotation as legacy Grease Pencil data (``clip.grease_pencil``,
``bpy.data.grease_pencils``), Blender 5 as ``clip.annotation`` (``bpy.data.annotations``, legacy
files are converted on load); both have layers → frames → strokes → points with ``co``, picked
here by feature, not by version. Measured in the real Blender 4.3 GUI (strokes drawn with
``gpencil.annotate`` at known places of the clip view) and on the bpy 5.0.1 wheel reading that file:
in the Movie Clip editor a point's ``co`` is in normalized frame coordinates like a Mask's —
x 0..1 left to right, y 0..1 bottom to top, z 0 — and frames are numbered in scene frames (the
clip's frame 1 is scene frame ``clip.frame_start``). Python can add layers and frames but not
strokes, in 4.3 and in 5.x alike.
"""
from __future__ import annotations

import os

import bpy
import numpy as np

from ...core.errors import InputError

DRAW = ("draw a closed line around the whole tree in the Movie Clip editor (toolbar › Annotation › Draw, "
        "or hold D and drag)")
HOW = f"{DRAW} on frame 1"


def _problem(short: str, message: str) -> InputError:
    """An InputError naming problem and fix, with a ``short`` form for the panel."""
    err = InputError(message)
    err.short = short
    return err


def _norm(path: str) -> str:
    return os.path.normcase(os.path.normpath(bpy.path.abspath(path)))


def clip_for_video(video_path: str):
    """The Movie Clip loaded from ``video_path`` (what *Open Clip to Draw Outline* opens), or None."""
    if not video_path:
        return None
    want = _norm(video_path)
    return next((c for c in bpy.data.movieclips if c.filepath and _norm(c.filepath) == want), None)


def clip_annotation(clip):
    """The clip's annotation data (``clip.annotation`` in Blender 5, ``clip.grease_pencil`` in 4.x)."""
    for attr in ("annotation", "grease_pencil"):
        if hasattr(clip, attr):
            return getattr(clip, attr)
    return None


def _active_layer(layers):
    layer = getattr(layers, "active", None)
    if layer is not None:
        return layer
    i = getattr(layers, "active_index", 0)
    return layers[i] if 0 <= i < len(layers) else layers[len(layers) - 1]


def _stroke_px(stroke, width: int, height: int) -> np.ndarray:
    pts = stroke.points
    dim = len(pts[0].co) if len(pts) else 3
    co = np.empty(len(pts) * dim, np.float64)
    pts.foreach_get("co", co)
    co = co.reshape(-1, dim)
    return np.stack([co[:, 0] * width, (1.0 - co[:, 1]) * height], axis=1)


#: a stroke is closed when its ends are at most this share of its bounding box's diagonal apart
CLOSED_GAP = 0.2
#: a closed stroke outlines a tree of its own when at least this share of the longest stroke's length
TREE_STROKE_SHARE = 0.25


def _strokes(clip, width: int, height: int) -> list[np.ndarray]:
    """Pixel polylines ``(M, 2)`` (x right, y down) of the strokes of 3 or more points drawn on
    ``clip``'s frame 1 on the active annotation layer (the layer's last frame at or before scene
    frame ``clip.frame_start``), placed on the image. Raises InputError naming the problem and
    the fix when there is none."""
    ann = clip_annotation(clip)
    if ann is None or len(ann.layers) == 0:
        raise _problem("No annotation on the clip yet",
                       f"clip '{clip.name}' has no annotation; {HOW}")
    layer = _active_layer(ann.layers)
    first = clip.frame_start
    frames = [f for f in layer.frames if f.frame_number <= first]
    if not frames:
        raise _problem("Nothing drawn on frame 1",
                       f"annotation layer '{layer.info}' of clip '{clip.name}' has nothing drawn on the clip's "
                       f"frame 1 (scene frame {first}); go to that frame and {DRAW}")
    frame = max(frames, key=lambda f: f.frame_number)
    found, n_strokes, n_view = [], 0, 0
    for stroke in frame.strokes:
        n_strokes += 1
        if len(stroke.points) < 3:
            continue
        px = _stroke_px(stroke, width, height)
        if np.abs(px / (width, height) - 0.5).max() > 1.0:      # percent of the region: placed on the view
            n_view += 1
            continue
        found.append(px)
    if not found and n_view:
        raise _problem("Stroke stuck to the view, not the image",
                       f"the annotation on clip '{clip.name}' was drawn with Stroke Placement 'View' (it does not "
                       "follow the image); set Stroke Placement to 'Image' in the clip editor's toolbar "
                       "(Annotation tab), erase the stroke and draw it again")
    if not found:
        what = "no stroke" if n_strokes == 0 else f"{n_strokes} stroke(s), each with fewer than 3 points"
        raise _problem("No stroke of 3+ points on frame 1",
                       f"annotation layer '{layer.info}' of clip '{clip.name}' has {what} on the clip's frame 1 "
                       f"(scene frame {frame.frame_number}); {HOW}")
    return found


def _length(px: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(px, axis=0), axis=1).sum())


def annotation_polygon(clip, width: int, height: int) -> np.ndarray:
    """Pixel polygon ``(M, 2)`` (x right, y down) of the outline drawn on ``clip``: of the active
    annotation layer, the drawing shown on the clip's frame 1 (the layer's last frame at or before
    scene frame ``clip.frame_start``), its longest stroke with 3 or more points. Raises InputError
    naming the problem and the fix."""
    return max(_strokes(clip, width, height), key=_length)


def annotation_polygons(clip, width: int, height: int) -> list[np.ndarray]:
    """The trees outlined on ``clip``'s frame 1 (issue 31: several trees in one shot): each closed
    stroke (ends at most :data:`CLOSED_GAP` of its box's diagonal apart) at least
    :data:`TREE_STROKE_SHARE` of the longest one's length, left to right; where fewer than two are,
    the longest stroke alone (:func:`annotation_polygon`: a tick or an open scribble beside the
    outline is no tree)."""
    found = _strokes(clip, width, height)
    longest = max(_length(px) for px in found)
    trees = [px for px in found if _length(px) >= TREE_STROKE_SHARE * longest
             and np.linalg.norm(px[0] - px[-1]) <= CLOSED_GAP * float(np.linalg.norm(np.ptp(px, axis=0)))]
    if len(trees) < 2:
        return [max(found, key=_length)]
    return sorted(trees, key=lambda px: float(px[:, 0].mean()))


def video_annotation_polygon(video_path: str, width: int, height: int) -> np.ndarray:
    """:func:`annotation_polygon` of the clip opened for ``video_path``."""
    clip = clip_for_video(video_path)
    if clip is None:
        raise _problem("No clip of this video is open",
                       f"no Movie Clip of '{os.path.basename(video_path)}' is loaded; press Open Clip to Draw "
                       f"Outline, then {HOW}")
    return annotation_polygon(clip, width, height)


def video_annotation_polygons(video_path: str, width: int, height: int) -> list[np.ndarray]:
    """:func:`annotation_polygons` of the clip opened for ``video_path``."""
    clip = clip_for_video(video_path)
    if clip is None:
        video_annotation_polygon(video_path, width, height)         # raises: no clip open
    return annotation_polygons(clip, width, height)


def status(video_path: str) -> tuple[bool, str]:
    """(usable, one short line) for the Outline panel."""
    clip = clip_for_video(video_path)
    try:
        if clip is None:
            video_annotation_polygon(video_path, 1, 1)
        size = clip.size
        polys = annotation_polygons(clip, int(size[0]) or 1, int(size[1]) or 1)
    except InputError as exc:
        return False, getattr(exc, "short", str(exc))
    if len(polys) > 1:
        return True, f"{len(polys)} trees outlined on '{clip.name}'"
    return True, f"Stroke of {len(polys[0])} points on '{clip.name}'"


def show_annotation_tools(area) -> None:
    """Show the Movie Clip editor's toolbar on its Annotation tab (Draw, Line, Poly, Erase); the clip
    editor has no Annotate tool in the tool system (4.3), its annotation tools live there."""
    space = area.spaces.active
    space.show_region_toolbar = True
    tools = next((r for r in area.regions if r.type == "TOOLS"), None)
    if tools is not None:
        try:
            tools.active_panel_category = "Annotation"
        except (TypeError, AttributeError):      # the tab list exists only after the first redraw
            pass
