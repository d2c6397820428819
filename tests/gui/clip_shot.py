"""GUI set-up for a screenshot of the Movie Clip editor with the tracks and 2D skeleton drawn over
the clip (Track & Preview, then the clip at frame 30).

    real-blender gui-shot docs/clip_overlay.png --size 1600x900 -- blender --factory-startup --python tests/gui/clip_shot.py
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import register_with_sample  # noqa: E402

props = register_with_sample()
print("preview:", bpy.ops.tree_video.preview("EXEC_DEFAULT"), flush=True)


def setup():
    screen = bpy.context.window.screen
    area = max(screen.areas, key=lambda a: a.width * a.height)
    area.type = "CLIP_EDITOR"
    space = area.spaces.active
    space.clip = bpy.data.movieclips.load(props.video_path)
    space.show_region_toolbar = False
    space.show_region_ui = False
    bpy.context.scene.frame_set(30)
    for region in area.regions:
        if region.type == "WINDOW":
            with bpy.context.temp_override(area=area, region=region):
                bpy.ops.clip.view_all(fit_view=True)
    area.tag_redraw()
    print("clip ready", flush=True)
    return None


bpy.app.timers.register(setup, first_interval=1.0)
