"""Outline from an annotation drawn over the clip (outline source "Annotation").

Python can't add annotation strokes (4.3 and 5.x), so the strokes come from
``tests/data/annotation_outline.blend``, drawn with the Annotate operator in the real Blender 4.3
GUI by ``tests/gui/make_annotation_fixture.py`` (legacy Grease Pencil data, which Blender 5 converts
to an Annotation on load). Layer "Note" (active): frame 1 — the tree's outline (outline.json) and a
2-point tick; frame 30 — a small triangle. Layer "Short": frame 1 — a 2-point stroke. Layer "View":
frame 1 — a triangle drawn with Stroke Placement "View" (percent of the region, not the image).
"""
import json
import os

import bpy
import numpy as np
import pytest

from tree_from_video.core.errors import InputError
from tree_from_video.core.outline import polygon_to_mask
from tree_from_video.operators import reconstruct_op
from tree_from_video.operators.scene import annotation

from samples import committed
from trees import addon  # noqa: F401  (autouse fixture: the add-on registered per test)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

HERE = os.path.dirname(os.path.abspath(__file__))
FIXTURE = os.path.join(HERE, "data", "annotation_outline.blend")
VIDEO = os.path.join(committed("broad"), "video.mp4")
W, H = 480, 360
with open(os.path.join(committed("broad"), "outline.json")) as _f:
    TRUE_OUTLINE = np.array(json.load(_f)["polygon"], float)




def _fixture_clip():
    """Append the fixture's clip (with its annotation) into the empty scene."""
    with bpy.data.libraries.load(FIXTURE) as (src, dst):
        assert src.movieclips == ["video.mp4"]
        dst.movieclips = list(src.movieclips)
    return dst.movieclips[0]


def _new_annotation(clip):
    """An empty annotation on ``clip`` (Blender 5: bpy.data.annotations; 4.x: legacy grease pencil)."""
    if hasattr(clip, "annotation"):
        clip.annotation = bpy.data.annotations.new("Python")
        return clip.annotation
    clip.grease_pencil = bpy.data.grease_pencils.new("Python")
    return clip.grease_pencil


def _dist_to_polyline(points, poly, closed=True):
    """Distance of each point to the nearest segment of ``poly``."""
    a = np.asarray(poly, float)
    b = np.roll(a, -1, axis=0) if closed else a[1:]
    a = a if closed else a[:-1]
    ab = b - a
    t = np.clip(((points[:, None] - a[None]) * ab[None]).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12)[None], 0, 1)
    return np.linalg.norm(points[:, None] - (a[None] + t[..., None] * ab[None]), axis=2).min(axis=1)


def test_annotation_stroke_is_the_trees_outline_in_pixels():
    clip = _fixture_clip()
    assert os.path.normpath(bpy.path.abspath(clip.filepath)) == VIDEO      # relative path resolved
    poly = annotation.annotation_polygon(clip, W, H)
    assert poly.shape == (477, 2)                                           # the long stroke, not the tick
    a, b = polygon_to_mask(poly, W, H), polygon_to_mask(TRUE_OUTLINE, W, H)
    iou = (a & b).sum() / (a | b).sum()
    d_out = _dist_to_polyline(poly, TRUE_OUTLINE)                           # stroke → outline.json
    d_in = _dist_to_polyline(TRUE_OUTLINE, poly)                            # outline.json → stroke
    print(f"annotation vs outline.json: IoU {iou:.4f}, stroke→outline max {d_out.max():.2f} px "
          f"(median {np.median(d_out):.2f}), outline→stroke max {d_in.max():.2f} px")
    assert iou >= 0.95
    assert d_out.max() < 2.0 and d_in.max() < 2.0
    # y down: the trunk's base (bottom of the outline) has the largest y
    assert poly[:, 1].max() == pytest.approx(TRUE_OUTLINE[:, 1].max(), abs=2.0)


def test_the_drawing_shown_on_the_clips_frame_1_is_used():
    clip = _fixture_clip()
    clip.frame_start = 29                      # frame 1 of the clip = scene frame 29: frame 1 still shown
    assert len(annotation.annotation_polygon(clip, W, H)) == 477
    clip.frame_start = 30                      # now the triangle drawn on scene frame 30
    tri = annotation.annotation_polygon(clip, W, H)
    assert len(tri) >= 3 and np.abs(tri.min(axis=0) - [40, 250]).max() < 2 and np.abs(tri.max(axis=0) - [100, 300]).max() < 2


@pytest.mark.parametrize("case", ["no clip", "no annotation", "no layer", "nothing on frame 1", "no stroke",
                                  "short stroke", "view placement"])
def test_missing_or_unusable_annotation_is_a_clear_error(case):
    if case == "no clip":
        with pytest.raises(InputError, match="no Movie Clip of 'video.mp4'.*Open Clip.*Annotation › Draw"):
            annotation.video_annotation_polygon(VIDEO, W, H)
        return
    if case in ("short stroke", "view placement"):
        clip = _fixture_clip()
        ann = annotation.clip_annotation(clip)
        ann.layers.active_index = 1 if case == "short stroke" else 2
        assert ann.layers[ann.layers.active_index].info == ("Short" if case == "short stroke" else "View")
        expect = ("layer 'Short'.* 1 stroke\\(s\\), each with fewer than 3 points.*Annotation › Draw"
                  if case == "short stroke" else "drawn with Stroke Placement 'View'.*set Stroke Placement to 'Image'")
    else:
        clip = bpy.data.movieclips.load(VIDEO)
        expect = "clip 'video.mp4' has no annotation.*Annotation › Draw"
        if case != "no annotation":
            ann = _new_annotation(clip)
            if case != "no layer":
                layer = ann.layers.new("Outline")
                if case == "nothing on frame 1":
                    layer.frames.new(5)
                    expect = "nothing drawn on the clip's frame 1 \\(scene frame 1\\).*Annotation › Draw"
                else:
                    layer.frames.new(1)
                    expect = "has no stroke on the clip's frame 1.*Annotation › Draw"
    with pytest.raises(InputError, match=expect):
        annotation.annotation_polygon(clip, W, H)
    assert annotation.status(VIDEO)[0] is False


def test_panel_status_names_the_stroke_or_the_problem():
    assert annotation.status(VIDEO) == (False, "No clip of this video is open")
    _fixture_clip()
    assert annotation.status(VIDEO) == (True, "Stroke of 477 points on 'video.mp4'")


def _run_op():
    try:
        return bpy.ops.tree_video.reconstruct("EXEC_DEFAULT"), ""
    except RuntimeError as exc:
        return {"CANCELLED"}, str(exc)


def test_reconstruct_with_annotation_outline(addon):
    addon.video_path, addon.outline_source = VIDEO, "ANNOTATION"
    addon.use_frame_range, addon.frame_start, addon.frame_end = True, 1, 24
    addon.collection_name = "Annotated"
    result, err = _run_op()                                   # no clip yet: refused, nothing added
    assert result == {"CANCELLED"} and "Annotated" not in bpy.data.collections
    clip = _fixture_clip()
    video, outline = reconstruct_op.inputs_from(addon)
    assert outline == pytest.approx(annotation.annotation_polygon(clip, W, H))
    result, err = _run_op()
    assert result == {"FINISHED"}, err
    rig = next(o for o in bpy.data.collections["Annotated"].objects if o.type == "ARMATURE")
    assert len(rig.data.bones) > 50


class _Points(list):
    """Stand-in for a stroke's points (Python cannot add strokes): ``co`` read by foreach_get."""

    def foreach_get(self, attr, out):
        out[:] = np.asarray([p.co for p in self], float).ravel()


class _Layers(list):
    active = property(lambda self: self[0])


def _fake_clip(strokes_px, w=W, h=H):
    """A clip-shaped stand-in whose active layer's frame 1 holds ``strokes_px`` (pixel polylines)."""
    from types import SimpleNamespace as NS
    strokes = [NS(points=_Points([NS(co=(x / w, 1.0 - y / h, 0.0)) for x, y in s])) for s in strokes_px]
    layer = NS(info="Note", frames=[NS(frame_number=1, strokes=strokes)])
    return NS(name="fake", frame_start=1, grease_pencil=NS(layers=_Layers([layer])))


def _loop(cx, cy, r, n=40, gap=0):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)[: n - gap]
    return np.stack([cx + r * np.cos(t), cy + r * np.sin(t)], 1)


def test_one_tree_per_closed_stroke_and_ticks_are_no_trees():
    """Issue 31: two closed strokes round two trees are two outlines (left to right); a tick, a
    small closed doodle or an open arc beside one outline leave it the only one, as before; the
    single-outline reader still takes the longest stroke."""
    both = [_loop(360, 180, 80), _loop(120, 180, 90)]
    two = annotation.annotation_polygons(_fake_clip(both), W, H)
    assert len(two) == 2 and two[0][:, 0].mean() < two[1][:, 0].mean()
    one = annotation.annotation_polygons(_fake_clip([_loop(200, 180, 100), [(10, 10), (30, 30), (50, 20)],
                                                     _loop(420, 60, 10), _loop(420, 250, 60, gap=20)]), W, H)
    assert len(one) == 1 and np.allclose(one[0], _loop(200, 180, 100), atol=1e-3)
    assert annotation.annotation_polygon(_fake_clip(both), W, H)[:, 0].mean() < 240      # the longer, left one
