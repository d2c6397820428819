"""Save and load the reconstruction settings as presets (Blender's preset system: small Python
files in the user's ``scripts/presets/tree_from_video`` folder)."""
import bpy
from bl_operators.presets import AddPresetBase

PRESET_SUBDIR = "tree_from_video"
#: settings a preset stores (not the per-shot paths, masks or names)
PRESET_VALUES = ["levels", "skeleton_kind", "conifer", "candidates", "solver", "sigma_track", "sigma_shape",
                 "max_step", "max_total", "height_m", "fit_branches", "build_mesh", "scale", "twig_depth", "curliness", "bark",
                 "build_leaves", "leaf_density", "leaf_cards", "max_leaf_clusters", "flutter_hz", "flutter_gain"]


class TREE_MT_presets(bpy.types.Menu):
    bl_label = "Tree from Video Presets"
    preset_subdir = PRESET_SUBDIR
    preset_operator = "script.execute_preset"
    draw = bpy.types.Menu.draw_preset


class TREE_OT_preset_add(AddPresetBase, bpy.types.Operator):
    """Save the current reconstruction settings as a preset (or remove the active one)"""

    bl_idname = "tree_video.preset_add"
    bl_label = "Add Tree from Video Preset"
    preset_menu = "TREE_MT_presets"
    preset_subdir = PRESET_SUBDIR
    # full paths, no preset_defines: Blender 4.3 on Python 3.13 cannot see names exec'd there (PEP 667)
    preset_values = [f"bpy.context.scene.tree_video.{name}" for name in PRESET_VALUES]


classes = (TREE_MT_presets, TREE_OT_preset_add)

register, unregister = bpy.utils.register_classes_factory(classes)
