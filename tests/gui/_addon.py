"""For the GUI scripts run inside Blender (``blender --python tests/gui/<script>.py``): load the
repository as the add-on ``tree_from_video``, register it, point it at the committed sample."""
import os
import sys

import bpy

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, ROOT)
from package_loader import load_package  # noqa: E402


def register_with_sample():
    """Register the add-on from the repo; return ``scene.tree_video`` set to sample_videos/broad."""
    pkg = load_package()
    pkg.register()
    bpy.context.preferences.view.show_splash = False
    props = bpy.context.scene.tree_video
    props.video_path = os.path.join(ROOT, "sample_videos", "broad", "video.mp4")
    props.outline_path = os.path.join(ROOT, "sample_videos", "broad", "outline.json")
    return props


def empty_stage():
    """Register the add-on (:func:`register_with_sample`), put ``tests/`` on the path and remove
    every object: a stage for trees built by hand."""
    sys.path.insert(0, os.path.join(ROOT, "tests"))
    props = register_with_sample()
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob)
    return props


def side_by_side(tree, gap: float, left: tuple, right: tuple) -> tuple[dict, dict]:
    """``tree`` built twice without leaves, ``left`` and ``right`` each ``(name, build_tree
    keywords)``, the right one ``gap`` metres along x: the two looks a shot compares."""
    from tree_from_video.operators.scene import build
    a = build.build_tree(bpy.context, tree, left[0], leaves=False, **left[1])
    b = build.build_tree(bpy.context, tree, right[0], leaves=False, **right[1])
    b["armature"].location.x = gap
    return a, b


def material_view(space, location, distance: float, rotation=(0.71, 0.70, 0.0, 0.0)) -> None:
    """The 3D view ``space`` in Material Preview without overlays, in perspective, looking at
    ``location`` from ``distance`` metres (``rotation`` the view's quaternion: from the front,
    level)."""
    space.shading.type = "MATERIAL"
    space.overlay.show_overlays = False
    r3d = space.region_3d
    r3d.view_perspective = "PERSP"
    r3d.view_rotation = rotation
    r3d.view_location = location
    r3d.view_distance = distance


def show_material(location, distance: float, rotation=(0.71, 0.70, 0.0, 0.0), frame: int | None = None,
                  solid: bool = False) -> None:
    """Once the window is up (a ``bpy.app.timers`` callback, retried until then): the first 3D view
    in :func:`material_view` at ``location``, ``distance``, ``rotation``; ``solid``: Solid shading
    with studio light and the materials' colours instead (the geometry without its maps); then
    ``frame`` (None: the current one) and "ui ready" printed."""
    def show():
        if bpy.context.window.screen is None:
            return 0.3
        area = next(a for a in bpy.context.window.screen.areas if a.type == "VIEW_3D")
        space = area.spaces.active
        material_view(space, location, distance, rotation)
        if solid:
            space.shading.type = "SOLID"
            space.shading.light = "STUDIO"
            space.shading.color_type = "MATERIAL"
        if frame is not None:
            bpy.context.scene.frame_set(frame)
        print("ui ready", flush=True)
        return None
    bpy.app.timers.register(show, first_interval=1.0)


def open_tree_tab(set_view, frame: int = 30):
    """A ``bpy.app.timers`` callback: open the 3D view's sidebar on the "Tree" tab (retrying until
    the tab list exists), solid shading, ``set_view(space, region_3d)`` for the camera, then go to
    ``frame`` and print "ui ready"."""
    def setup_ui():
        for area in bpy.context.window.screen.areas:
            if area.type != "VIEW_3D":
                continue
            space = area.spaces.active
            space.show_region_ui = True
            space.shading.type = "SOLID"
            region = next(r for r in area.regions if r.type == "UI")
            try:
                region.active_panel_category = "Tree"
            except (TypeError, AttributeError):
                return 0.3            # the tab list does not exist yet: try again after a redraw
            set_view(space, space.region_3d)
            bpy.context.scene.frame_set(frame)
            area.tag_redraw()
            print("ui ready", flush=True)
            return None
        return 0.3
    return setup_ui
