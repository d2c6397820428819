"""Load this folder as the package ``tree_from_video`` when it is not installed as an extension.

The one recipe for ``batch.py``, the tests, the benchmarks, the scripts and the GUI scripts run
inside Blender (an installed extension is imported by Blender as ``bl_ext.<repo>.tree_from_video``
and needs none of this)::

    sys.path.insert(0, REPO)          # the folder holding this file
    from package_loader import load_package, load_module
    cli = load_module("cli")
"""
from __future__ import annotations

import importlib
import importlib.util
import os
import sys
from types import ModuleType

ROOT = os.path.dirname(os.path.abspath(__file__))
PACKAGE = "tree_from_video"


def load_package() -> ModuleType:
    """The package ``tree_from_video`` (this folder), imported once."""
    if PACKAGE in sys.modules:
        return sys.modules[PACKAGE]
    spec = importlib.util.spec_from_file_location(PACKAGE, os.path.join(ROOT, "__init__.py"),
                                                  submodule_search_locations=[ROOT])
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[PACKAGE]
        raise
    return module


def load_module(name: str) -> ModuleType:
    """The submodule ``tree_from_video.<name>`` (e.g. ``"cli"``, ``"core.pipeline"``)."""
    return importlib.import_module(f"{load_package().__name__}.{name}")
