"""Make ``tests/data/annotation_outline.blend``: a Movie Clip of sample_videos/broad with annotation
strokes drawn by the Annotate tool (``gpencil.annotate`` with a recorded ``stroke``, as a mouse drag
would) in the real Blender 4.3 GUI. Neither 4.x nor 5.x Python can add strokes to annotations, so
the tests read this file.

    real-blender gui-shot /tmp/fixture.png --size 1600x900 -- \\
        blender --factory-startup --python tests/gui/make_annotation_fixture.py

Contents (the clip is saved alone with ``bpy.data.libraries.write``, its path relative):
layer "Note" (active): frame 1 — the tree's outline (sample_videos/broad/outline.json, closed, a
point every ~2 px) and a 2-point tick in the sky; frame 30 — a small triangle.
Layer "Short": frame 1 — one 2-point stroke. Layer "View": frame 1 — a triangle drawn with Stroke
Placement "View" (stored in percent of the region instead of the image's 0..1).
"""
import json
import os

import bpy
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
VIDEO = os.path.join(ROOT, "sample_videos", "broad", "video.mp4")
OUTLINE = os.path.join(ROOT, "sample_videos", "broad", "outline.json")
OUT = os.path.join(ROOT, "tests", "data", "annotation_outline.blend")


def _clip_area():
    area = next(a for a in bpy.context.window.screen.areas if a.type == "CLIP_EDITOR")
    return area, next(r for r in area.regions if r.type == "WINDOW")


def _dense(poly_px, step=2.0, closed=True):
    """Points every ``step`` px along the polygon (as a mouse drag records them)."""
    p = np.asarray(poly_px, float)
    if closed:
        p = np.vstack([p, p[:1]])
    out = []
    for a, b in zip(p[:-1], p[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out += [a + (b - a) * t for t in np.arange(n) / n]
    out.append(p[-1])
    return np.array(out)


def _draw(poly_px, w, h):
    """One stroke through ``poly_px`` (video pixels, y down) with the Annotate operator."""
    area, region = _clip_area()
    v2d = region.view2d
    stroke = []
    for i, (x, y) in enumerate(poly_px):
        mx, my = v2d.view_to_region(x / w, 1.0 - y / h, clip=False)   # the clip view is 0..1, y up
        stroke.append({"name": "", "mouse": (mx, my), "mouse_event": (mx, my), "location": (0, 0, 0),
                       "pressure": 1.0, "size": 0, "pen_flip": False, "x_tilt": 0, "y_tilt": 0,
                       "time": 0.01 * i, "is_start": i == 0})
    with bpy.context.temp_override(area=area, region=region):
        return bpy.ops.gpencil.annotate(mode="DRAW", stroke=stroke, wait_for_input=False)


def setup():
    bpy.context.preferences.view.show_splash = False
    area = max(bpy.context.window.screen.areas, key=lambda a: a.width * a.height)
    area.type = "CLIP_EDITOR"
    space = area.spaces.active
    space.clip = bpy.data.movieclips.load(VIDEO)
    space.show_region_toolbar = False
    space.show_region_ui = False
    bpy.context.scene.frame_set(1)
    bpy.app.timers.register(fit, first_interval=1.0)


def fit():
    area, region = _clip_area()
    with bpy.context.temp_override(area=area, region=region):
        bpy.ops.clip.view_all(fit_view=True)
    bpy.app.timers.register(draw, first_interval=0.5)


def draw():
    area, region = _clip_area()
    clip = area.spaces.active.clip
    w, h = clip.size
    v2d = region.view2d
    print("1 video px =", (v2d.view_to_region(1, 1, clip=False)[0] - v2d.view_to_region(0, 0, clip=False)[0]) / w,
          "region px", flush=True)
    with open(OUTLINE) as f:
        poly = np.array(json.load(f)["polygon"], float)
    scene = bpy.context.scene
    print("tree:", _draw(_dense(poly), w, h), flush=True)
    print("tick:", _draw([(30, 30), (90, 30)], w, h), flush=True)
    scene.frame_set(30)
    print("triangle:", _draw(_dense([(40, 300), (100, 300), (70, 250)]), w, h), flush=True)
    scene.frame_set(1)
    gp = clip.grease_pencil
    gp.layers.new("Short")
    gp.layers.active_index = len(gp.layers) - 1
    print("short:", _draw([(400, 40), (440, 60)], w, h), flush=True)
    gp.layers.new("View")
    gp.layers.active_index = len(gp.layers) - 1
    ts = scene.tool_settings
    ts.annotation_stroke_placement_view2d = "VIEW"         # stored in percent of the region, not the image
    print("view-placed:", _draw(_dense([(300, 300), (400, 300), (350, 250)]), w, h), flush=True)
    ts.annotation_stroke_placement_view2d = "IMAGE"
    gp.layers.active_index = 0
    for layer in gp.layers:
        for fr in layer.frames:
            print(f"layer {layer.info!r} frame {fr.frame_number}: strokes of",
                  [len(s.points) for s in fr.strokes], "points", flush=True)
    s = max(gp.layers[0].frames[0].strokes, key=lambda s: len(s.points))
    co = np.array([p.co[:2] for p in s.points])
    px = np.stack([co[:, 0] * w, (1.0 - co[:, 1]) * h], axis=1)
    d = np.linalg.norm(px[:, None] - _dense(poly, 0.25)[None], axis=2).min(axis=1)
    print(f"stored tree stroke: {len(px)} points, distance to outline.json max {d.max():.2f} px, "
          f"median {np.median(d):.2f} px", flush=True)
    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    if os.path.exists(OUT):
        os.remove(OUT)
    bpy.data.libraries.write(OUT, {clip}, path_remap="RELATIVE", compress=True)
    print("wrote", OUT, os.path.getsize(OUT), "bytes", flush=True)
    return None


if __name__ == "__main__":
    bpy.app.timers.register(setup, first_interval=1.0)
