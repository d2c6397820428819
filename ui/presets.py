"""Save and load the reconstruction settings as presets (Blender's preset system: small Python
files in the user's ``scripts/presets/tree_from_video`` folder). A few ship with the add-on
(``presets/tree_from_video``: Default, Conifer, Quick Look), so the menu is never empty (it read
"* Missing Paths *" before the first preset was saved); they cannot be removed."""
import os

import bpy
from bl_operators.presets import AddPresetBase

PRESET_SUBDIR = "tree_from_video"
#: the add-on's folder: its ``presets/tree_from_video`` holds the shipped presets
PACKAGE_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHIPPED_DIR = os.path.join(PACKAGE_DIR, "presets", PRESET_SUBDIR)
#: settings a preset stores (not the per-shot paths, masks or names)
PRESET_VALUES = ["levels", "skeleton_kind", "form", "limbs", "candidates", "solver", "sigma_track", "sigma_shape",
                 "max_step", "max_total", "height_m", "fit_branches", "build_mesh", "scale", "twig_depth", "curliness", "bark",
                 "forks", "bark_relief",
                 "build_leaves", "leaf_density", "leaf_cards", "max_leaf_clusters", "flutter_hz", "flutter_gain",
                 "leaf_colour_mode", "leaf_colour_custom"]


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

    def execute(self, context):
        label = getattr(bpy.types, self.preset_menu).bl_label      # the chosen preset (execute_preset sets it)
        if self.remove_active and label in shipped_presets():
            self.report({"WARNING"}, f"preset '{label}' ships with the add-on and cannot be removed; "
                                     "choose one you saved")
            return {"CANCELLED"}
        return super().execute(context)


def shipped_presets() -> list[str]:
    """Display names of the presets shipped with the add-on."""
    if not os.path.isdir(SHIPPED_DIR):
        return []
    return sorted(bpy.path.display_name(os.path.splitext(f)[0], title_case=False)
                  for f in os.listdir(SHIPPED_DIR) if f.endswith(".py"))


classes = (TREE_MT_presets, TREE_OT_preset_add)

_register, _unregister = bpy.utils.register_classes_factory(classes)


def register():
    _register()
    if hasattr(bpy.utils, "register_preset_path"):         # the shipped presets join the menu
        bpy.utils.register_preset_path(PACKAGE_DIR)


def unregister():
    if hasattr(bpy.utils, "unregister_preset_path"):
        bpy.utils.unregister_preset_path(PACKAGE_DIR)
    _unregister()
