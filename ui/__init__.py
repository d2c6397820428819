"""The "Tree from Video" sidebar panel and its scene properties (registered in this order)."""
import bpy

register, unregister = bpy.utils.register_submodule_factory(__name__, ["properties", "presets", "panel"])
