"""GUI set-up for a screenshot of a generated forest and the Generate panel: register the add-on
from the repo, grow a small forest of the bundled "broad" species, and open the sidebar on the
"Tree" tab.

    real-blender gui-shot docs/generate.png --size 1600x1000 -- blender --factory-startup --python tests/gui/generate_shot.py
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import open_tree_tab, register_with_sample  # noqa: E402


def forest_view(space, r3d):
    space.shading.color_type = "TEXTURE"
    r3d.view_perspective = "PERSP"
    r3d.view_rotation = (0.82, 0.55, 0.08, 0.12)
    r3d.view_location = (0.0, 0.0, 4.0)
    r3d.view_distance = 48.0


def forest_shot(**settings):
    """The forest (and the screenshot's view); ``settings`` more panel properties by name, set
    before the forest grows (tests/gui/variety_shot.py: its own crown per tree)."""
    props = register_with_sample()
    for ob in list(bpy.data.objects):          # an empty stage for the forest
        bpy.data.objects.remove(ob)
    props.species_source, props.species_name = "LIBRARY", "broad"
    props.envelope_source = "CIRCLE"
    props.gen_nodes, props.gen_frames, props.gen_height = 160, 96, 8.0
    props.forest_count, props.forest_spacing, props.forest_width, props.forest_depth = 7, 9.0, 36.0, 24.0
    for name, value in settings.items():
        setattr(props, name, value)
    print("forest:", bpy.ops.tree_video.generate_forest("EXEC_DEFAULT"), flush=True)
    print("selected after the forest:", len(bpy.context.selected_objects), flush=True)

    # show the Generate sub-panel: start the reconstruction sub-panels closed (screenshot only)
    from tree_from_video.ui import panel

    for cls in (panel.TREE_PT_source, panel.TREE_PT_outline, panel.TREE_PT_reconstruction, panel.TREE_PT_output):
        bpy.utils.unregister_class(cls)
        cls.bl_options = {"DEFAULT_CLOSED"}
        bpy.utils.register_class(cls)
    bpy.app.timers.register(open_tree_tab(forest_view), first_interval=1.0)


if __name__ == "__main__":
    forest_shot()
