"""GUI set-up for a screenshot of a forest whose trees each grow in their own crown (issue 36:
*Crown Variety* 0.7, seed 000's contour space) with *Holton Angles* on, the Generate panel beside it.

    real-blender gui-shot docs/crown_variety.png --size 1600x1000 -- blender --factory-startup \
        --python tests/gui/variety_shot.py
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import open_tree_tab, register_with_sample  # noqa: E402

props = register_with_sample()
for ob in list(bpy.data.objects):          # an empty stage for the forest
    bpy.data.objects.remove(ob)
props.species_source, props.species_name = "LIBRARY", "broad"
props.envelope_source = "CIRCLE"
props.gen_nodes, props.gen_frames, props.gen_height = 160, 96, 8.0
props.forest_count, props.forest_spacing, props.forest_width, props.forest_depth = 7, 9.0, 36.0, 24.0
props.forest_variants = 0                  # every tree its own crown
props.gen_envelope_variation, props.gen_allometry = 0.7, True
print("forest:", bpy.ops.tree_video.generate_forest("EXEC_DEFAULT"), flush=True)
print("selected after the forest:", len(bpy.context.selected_objects), flush=True)

# show the Generate sub-panel: start the reconstruction sub-panels closed (screenshot only)
from tree_from_video.ui import panel  # noqa: E402

for cls in (panel.TREE_PT_source, panel.TREE_PT_outline, panel.TREE_PT_reconstruction, panel.TREE_PT_output):
    bpy.utils.unregister_class(cls)
    cls.bl_options = {"DEFAULT_CLOSED"}
    bpy.utils.register_class(cls)


def forest_view(space, r3d):
    space.shading.color_type = "TEXTURE"
    r3d.view_perspective = "PERSP"
    r3d.view_rotation = (0.82, 0.55, 0.08, 0.12)
    r3d.view_location = (0.0, 0.0, 4.0)
    r3d.view_distance = 48.0


bpy.app.timers.register(open_tree_tab(forest_view), first_interval=1.0)
