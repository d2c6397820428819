"""Show a video in the Movie Clip editor (what Track & Preview opens): its clip loaded once,
on a given frame, fitted to the editor, with the overlay's tracks and skeleton drawn on it.

In the GUI an existing Movie Clip editor of the window is reused; else the 3D view (the one the
button was pressed in, or the largest) is split in two and its left half becomes the clip
editor (sidebar on the Tree tab, no toolbar), so the 3D view's panel stays where it was and no
window is opened. In background mode only the clip and the scene frame are set.
"""
from __future__ import annotations

import bpy

from . import annotation


def clip_for(video: str):
    """The Movie Clip of ``video`` (an absolute path): the one already loaded, else a new one."""
    return annotation.clip_for_video(video) or bpy.data.movieclips.load(video)


def show_clip(context, clip, clip_frame: int = 1):
    """Go to ``clip_frame`` (1-based, of ``clip``) and show ``clip`` fitted in a Movie Clip editor
    of the window; returns that area, or None in background mode or without a window. A clip
    editor made here gets its sidebar on the Tree tab and no toolbar."""
    context.scene.frame_set(clip.frame_start + clip_frame - 1)
    window, screen = getattr(context, "window", None), getattr(context, "screen", None)
    if bpy.app.background or window is None or screen is None:
        return None
    area, made = clip_area(context, window, screen)
    if area is None:
        return None
    space = area.spaces.active
    space.clip = clip
    space.mode, space.view = "TRACKING", "CLIP"
    overlay = getattr(space, "overlay", None)          # Blender 5: the editor's overlays toggle
    if overlay is not None:
        overlay.show_overlays = True
    if made:
        space.show_region_toolbar, space.show_region_ui = False, True
    _fit_later(window, area, "Tree" if made else None)
    return area


def clip_area(context, window, screen) -> tuple:
    """``(area, made)``: a Movie Clip editor area of ``screen`` — the one the button was pressed
    in, another one, else (``made``) the left half of a 3D view split in two (the one the button
    was pressed in, or the largest; the right half keeps the 3D view and its sidebar)."""
    here = getattr(context, "area", None)
    if here is not None and here.type == "CLIP_EDITOR":
        return here, False
    area = next((a for a in screen.areas if a.type == "CLIP_EDITOR"), None)
    if area is not None:
        return area, False
    views = [a for a in screen.areas if a.type == "VIEW_3D"]
    target = here if here is not None and here.type == "VIEW_3D" else \
        max(views or list(screen.areas), key=lambda a: a.width * a.height, default=None)
    if target is None:
        return None, False
    before = {a.as_pointer() for a in screen.areas}
    region = next((r for r in target.regions if r.type == "WINDOW"), None)
    with context.temp_override(window=window, screen=screen, area=target, region=region):
        try:
            bpy.ops.screen.area_split(direction="VERTICAL", factor=0.5)
        except RuntimeError:                            # too small to split
            pass
    # the new area (a copy of the 3D view) is the left half, the split one keeps the right half and
    # its sidebar (measured in Blender 4.3; areas get their new size only at the next redraw)
    new = next((a for a in screen.areas if a.as_pointer() not in before), None)
    if new is None:                                     # not split: the 3D view becomes the clip editor
        new = target
    new.type = "CLIP_EDITOR"
    return new, True


def _fit_later(window, area, tab: str | None) -> None:
    """Once ``area`` is laid out (its size unchanged over two timer ticks, after the redraws that
    follow a split or a sidebar shown): open its sidebar on ``tab`` (if given), then fit the clip."""
    pointer, tries, seen = area.as_pointer(), [0], [None]

    def fit():
        tries[0] += 1
        again = 0.1 if tries[0] < 30 else None
        try:
            found = next((a for a in window.screen.areas if a.as_pointer() == pointer), None)
        except ReferenceError:                          # the window was closed
            return None
        if found is None or found.type != "CLIP_EDITOR":
            return None
        region = next((r for r in found.regions if r.type == "WINDOW"), None)
        if region is None or region.width < 8 or region.height < 8:
            return again
        if tab:
            sidebar = next((r for r in found.regions if r.type == "UI"), None)
            try:
                if sidebar is not None and sidebar.active_panel_category != tab:
                    sidebar.active_panel_category = tab
            except (TypeError, AttributeError):         # the tab list exists after the first redraw
                return again
        size = (found.x, found.width, region.width, region.height)
        if size != seen[0]:
            seen[0] = size
            return again
        with bpy.context.temp_override(window=window, area=found, region=region):
            bpy.ops.clip.view_all(fit_view=True)
        found.tag_redraw()
        return None
    bpy.app.timers.register(fit, first_interval=0.05)
