"""Shown instead of the add-on when its Python dependencies are missing (imports bpy only)."""
import importlib.util

import bpy

#: import name → the wheel that provides it
DEPENDENCIES = {"numpy": "numpy", "scipy": "scipy", "cv2": "opencv-contrib-python-headless"}


def missing_dependencies() -> list[str]:
    """Wheels whose module cannot be found in this Blender's Python."""
    return [wheel for mod, wheel in DEPENDENCIES.items() if importlib.util.find_spec(mod) is None]


def message(missing: list[str]) -> str:
    return (f"Tree from Video cannot start: missing {', '.join(missing)}. Reinstall the extension zip "
            "made for your platform (it bundles these wheels), or install them into Blender's Python.")


class TREE_PT_missing(bpy.types.Panel):
    bl_label = "Tree from Video"
    bl_idname = "TREE_PT_missing"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Tree"

    missing: list = []

    def draw(self, context):
        col = self.layout.column()
        col.alert = True
        col.label(text="Missing dependencies:", icon="ERROR")
        for wheel in self.missing:
            col.label(text=f"  {wheel}")
        col.label(text="Reinstall the extension zip")
        col.label(text="made for your platform.")


def register(missing: list[str]) -> None:
    TREE_PT_missing.missing = list(missing)
    bpy.utils.register_class(TREE_PT_missing)
    print(message(missing))


def unregister() -> None:
    if TREE_PT_missing.is_registered:
        bpy.utils.unregister_class(TREE_PT_missing)
