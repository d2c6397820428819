"""GUI set-up for a screenshot of the panel: register the add-on from the repo, reconstruct the
sample tree, open the sidebar (default width) on the "Tree" tab with the reconstruction's
sub-panels expanded. The tree in the viewport, Solid view: no bone sticks, no selection outline,
leaves in their own green (printed as a "viewport:" line the CI checks).

    real-blender gui-shot docs/panel.png --size 1600x1280 -- blender --factory-startup --python tests/gui/panel_shot.py
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import open_tree_tab, register_with_sample  # noqa: E402

props = register_with_sample()
for ob in list(bpy.data.objects):          # an empty stage for the tree
    bpy.data.objects.remove(ob)
props.use_frame_range, props.frame_start, props.frame_end = True, 1, 60
props.show_advanced = True
props.collection_name = "Broad Tree"
print("reconstruct:", bpy.ops.tree_video.reconstruct("EXEC_DEFAULT"), flush=True)
tree = bpy.data.collections["Broad Tree"]
rig = next(ob for ob in tree.objects if ob.type == "ARMATURE")
leaf = next(ob for ob in tree.objects if ob.name.endswith("Leaves")).data.materials[0].diffuse_color
print(f"viewport: {sum(ob.select_get() for ob in tree.objects)} selected, "
      f"bones hidden {all(not any(c.is_visible for c in b.collections) for b in rig.data.bones)}, "
      f"leaf solid colour green {leaf[1] > 1.2 * max(leaf[0], leaf[2])}", flush=True)


def front_view(space, r3d):
    r3d.view_perspective = "ORTHO"
    r3d.view_rotation = (0.7071, 0.7071, 0.0, 0.0)      # front view
    r3d.view_location = (0.0, 0.0, 5.0)
    r3d.view_distance = 14.0


bpy.app.timers.register(open_tree_tab(front_view), first_interval=1.0)
