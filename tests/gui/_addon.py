"""For the GUI scripts run inside Blender (``blender --python tests/gui/<script>.py``): load the
repository as the add-on ``tree_from_video``, register it, point it at the committed sample."""
import importlib.util
import os
import sys

import bpy

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def register_with_sample():
    """Register the add-on from the repo; return ``scene.tree_video`` set to sample_videos/broad."""
    spec = importlib.util.spec_from_file_location("tree_from_video", os.path.join(ROOT, "__init__.py"),
                                                  submodule_search_locations=[ROOT])
    pkg = importlib.util.module_from_spec(spec)
    sys.modules["tree_from_video"] = pkg
    spec.loader.exec_module(pkg)
    pkg.register()
    bpy.context.preferences.view.show_splash = False
    props = bpy.context.scene.tree_video
    props.video_path = os.path.join(ROOT, "sample_videos", "broad", "video.mp4")
    props.outline_path = os.path.join(ROOT, "sample_videos", "broad", "outline.json")
    return props
