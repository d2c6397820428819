"""Tree from Video — a Blender extension that turns a video of a tree in wind into an animated 3D
tree.

The package root imports no bpy: ``core/`` is pure Python (numpy/scipy/OpenCV) and can be used in
tests, worker threads and batch runs; ``operators/`` and ``ui/`` are loaded by :func:`register`.
"""
__version__ = "0.1.0"


CLI_ID = "tree_from_video"
_cli_handle = None


def _cli(argv: list[str]) -> int:
    """``blender -c tree_from_video VIDEO --outline ... --out DIR [options]``: the batch job."""
    from . import cli
    try:
        return cli.main(argv)
    except SystemExit as exc:          # argparse: --help (0) or a usage error (2)
        return int(exc.code or 0)


_degraded = False


def __getattr__(name: str):
    """``tree_from_video.api`` (the scripting API) without importing it at add-on load time."""
    if name == "api":
        import importlib
        return importlib.import_module(".api", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def register():
    global _cli_handle, _degraded
    import bpy

    from .ui import missing_deps
    missing = missing_deps.missing_dependencies()
    if missing:                       # a panel that names the missing wheels, nothing else
        _degraded = True
        missing_deps.register(missing)
        return
    from . import operators, ui
    operators.register()
    ui.register()
    if hasattr(bpy.utils, "register_cli_command"):
        _cli_handle = bpy.utils.register_cli_command(CLI_ID, _cli)


def unregister():
    global _cli_handle, _degraded
    import bpy

    if _degraded:
        from .ui import missing_deps
        missing_deps.unregister()
        _degraded = False
        return
    from . import operators, ui
    if _cli_handle is not None:
        bpy.utils.unregister_cli_command(_cli_handle)
        _cli_handle = None
    ui.unregister()
    operators.unregister()
