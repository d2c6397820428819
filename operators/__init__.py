"""Blender operators (the thin bpy layer over ``core``)."""
import bpy

register, unregister = bpy.utils.register_submodule_factory(__name__, ["skeleton_op", "reconstruct_op", "export_op", "generate_op"])
