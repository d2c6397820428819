"""GUI check of the annotation outline as a user makes it: outline source "Annotation", *Open Clip to
Draw Outline* (the Movie Clip editor in Tracking mode, its toolbar on the Annotation tab), a closed
line drawn around the tree (the annotate operator fed a recorded drag along sample_videos/broad/outline.json),
then Track & Preview from that outline; the sidebar's Outline panel shows the stroke it found.

    real-blender gui-shot /tmp/annotation.png --size 1600x900 --wait 12 -- \\
        blender --factory-startup --python tests/gui/annotation_shot.py
"""
import json
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from make_annotation_fixture import _dense, _draw  # noqa: E402

from _addon import ROOT, register_with_sample  # noqa: E402

props = register_with_sample()
props.outline_source = "ANNOTATION"


def split():
    screen = bpy.context.window.screen
    area = max(screen.areas, key=lambda a: a.width * a.height)          # the 3D viewport
    with bpy.context.temp_override(area=area):
        bpy.ops.screen.area_split(direction="VERTICAL", factor=0.6)
    left = min((a for a in screen.areas if a.type == "VIEW_3D"), key=lambda a: a.x)
    left.type = "CLIP_EDITOR"                                            # as the user would
    bpy.app.timers.register(open_clip, first_interval=0.5)


def open_clip():
    screen = bpy.context.window.screen
    area = next(a for a in screen.areas if a.type == "CLIP_EDITOR")
    with bpy.context.temp_override(area=area):
        print("open_clip:", bpy.ops.tree_video.open_clip(), flush=True)
    space = area.spaces.active
    print(f"clip editor mode {space.mode}, toolbar shown {space.show_region_toolbar}", flush=True)
    print("status before drawing:", __import__("tree_from_video").operators.scene.annotation.status(props.video_path),
          flush=True)
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(area=area, region=region):
        bpy.ops.clip.view_all(fit_view=True)
    bpy.app.timers.register(draw, first_interval=0.5)


def draw():
    with open(os.path.join(ROOT, "sample_videos", "broad", "outline.json")) as f:
        poly = json.load(f)["polygon"]
    print("annotate:", _draw(_dense(poly), 480, 360), flush=True)
    from tree_from_video.operators.scene import annotation
    print("status after drawing:", annotation.status(props.video_path), flush=True)
    props.use_frame_range, props.frame_start, props.frame_end = True, 1, 30
    print("preview:", bpy.ops.tree_video.preview("EXEC_DEFAULT"), flush=True)
    bpy.app.timers.register(sidebar, first_interval=0.3)


def sidebar():
    for area in bpy.context.window.screen.areas:
        if area.type == "VIEW_3D":
            area.spaces.active.show_region_ui = True
            region = next(r for r in area.regions if r.type == "UI")
            try:
                region.active_panel_category = "Tree"
            except (TypeError, AttributeError):
                return 0.3
            area.tag_redraw()
    bpy.context.scene.frame_set(1)
    print("ui ready", flush=True)
    return None


bpy.app.timers.register(split, first_interval=1.0)
