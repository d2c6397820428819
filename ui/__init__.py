"""The "Tree from Video" sidebar panel and its scene properties."""
from . import panel, properties

_modules = (properties, panel)


def register():
    for m in _modules:
        m.register()


def unregister():
    for m in reversed(_modules):
        m.unregister()
