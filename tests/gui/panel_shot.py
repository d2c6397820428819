"""GUI set-up for a screenshot of the panel: register the add-on from the repo, reconstruct the
sample tree, open the sidebar on the "Tree" tab with every sub-panel expanded.

    real-blender gui-shot docs/panel.png --size 1600x900 -- blender --factory-startup --python tests/gui/panel_shot.py
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import open_tree_tab, register_with_sample  # noqa: E402

props = register_with_sample()
for ob in list(bpy.data.objects):          # an empty stage for the tree
    bpy.data.objects.remove(ob)
props.use_frame_range, props.frame_start, props.frame_end = True, 0, 60
props.show_advanced = True
props.collection_name = "Broad Tree"
print("reconstruct:", bpy.ops.tree_video.reconstruct("EXEC_DEFAULT"), flush=True)


def front_view(space, r3d):
    r3d.view_perspective = "ORTHO"
    r3d.view_rotation = (0.7071, 0.7071, 0.0, 0.0)      # front view
    r3d.view_location = (0.0, 0.0, 5.0)
    r3d.view_distance = 14.0


bpy.app.timers.register(open_tree_tab(front_view), first_interval=1.0)
