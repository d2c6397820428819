"""GUI set-up for a screenshot of Track & Preview as a user sees it: pressed in the 3D view's Tree
panel, the operator itself splits the 3D view and opens the Movie Clip editor in its left half
with the video's clip on its first frame, fitted, its sidebar on the Tree tab (the same panel),
the tracks and 2D skeleton drawn over the clip. The script only presses the button and, when
the clip editor is set up, goes to frame 30.

    real-blender gui-shot docs/clip_overlay.png --size 1600x900 --wait 15 -- \
        blender --factory-startup --python tests/gui/clip_shot.py
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import register_with_sample  # noqa: E402

props = register_with_sample()


def _areas(kind):
    return [a for a in bpy.context.window.screen.areas if a.type == kind]


def press_preview():
    """Track & Preview pressed in the 3D view's sidebar (EXEC: the GUI waits for it, as a script can)."""
    if _areas("CLIP_EDITOR"):
        print("a clip editor was open before the preview", flush=True)
        return None
    window = bpy.context.window
    view = max(_areas("VIEW_3D"), key=lambda a: a.width)
    view.spaces.active.show_region_ui = True
    region = next(r for r in view.regions if r.type == "UI")
    try:
        region.active_panel_category = "Tree"
    except (TypeError, AttributeError):
        return 0.3                # the tab list does not exist yet: try again after a redraw
    with bpy.context.temp_override(window=window, screen=window.screen, area=view, region=region):
        print("preview:", bpy.ops.tree_video.preview("EXEC_DEFAULT"), flush=True)
    bpy.app.timers.register(check, first_interval=0.5)
    return None


def check(tries=[0]):  # noqa: B006  (a counter kept between timer calls)
    """Let the operator's clip editor be laid out and fitted, then report it and go to frame 30."""
    tries[0] += 1
    clips = _areas("CLIP_EDITOR")
    if len(clips) != 1:
        print(f"the preview opened {len(clips)} clip editors", flush=True)
        return None
    area = clips[0]
    space = area.spaces.active
    sidebar = next(r for r in area.regions if r.type == "UI")
    if tries[0] < 8:                                       # 2 s: the operator fits the clip once it is laid out
        return 0.25
    view = _areas("VIEW_3D")
    print(f"clip editor opened by the operator: clip {space.clip.name if space.clip else None}, "
          f"frame {bpy.context.scene.frame_current}, zoom {space.zoom_percentage:.0f}%, sidebar "
          f"{space.show_region_ui} on tab {sidebar.active_panel_category!r}, x {area.x} (3D view x {view[0].x})",
          flush=True)
    bpy.context.scene.frame_set(30)
    area.tag_redraw()
    print("clip ready", flush=True)
    return None


bpy.app.timers.register(press_preview, first_interval=1.0)
