"""Blender operators (the thin bpy layer over ``core``)."""
from . import skeleton_op

_modules = (skeleton_op,)


def register():
    for m in _modules:
        m.register()


def unregister():
    for m in reversed(_modules):
        m.unregister()
