"""Tree from Video — a Blender extension that turns a video of a tree in wind into an animated 3D
tree.

The package root imports no bpy: ``core/`` is pure Python (numpy/scipy/OpenCV) and can be used in
tests, worker threads and batch runs; ``operators/`` and ``ui/`` are loaded by :func:`register`.
"""
__version__ = "0.1.0"


def register():
    from . import operators, ui
    operators.register()
    ui.register()


def unregister():
    from . import operators, ui
    ui.unregister()
    operators.unregister()
