"""Load the repository root as the package ``tree_from_video`` (as the tests and batch.py do)."""
import importlib.util
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def load_package():
    if "tree_from_video" in sys.modules:
        return sys.modules["tree_from_video"]
    spec = importlib.util.spec_from_file_location("tree_from_video", os.path.join(ROOT, "__init__.py"),
                                                  submodule_search_locations=[ROOT])
    mod = importlib.util.module_from_spec(spec)
    sys.modules["tree_from_video"] = mod
    spec.loader.exec_module(mod)
    return mod
