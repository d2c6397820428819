"""Reconstruct the committed sample through an *installed* Tree from Video package (used by
scripts/test_extension.sh).

In a Blender where the extension zip was installed and enabled (clean user dir):

    blender -b --python-exit-code 1 --python scripts/extension_check.py -- \
        --module bl_ext.user_default.tree_from_video --sample sample_videos/broad

With the bpy wheel in a venv holding the zip's wheels, the add-on folder extracted from the zip:

    venv/bin/python scripts/extension_check.py --package-dir DIR/tree_from_video --sample sample_videos/broad

Checks that the add-on is enabled (Blender) or registers (wheel), runs the public API on the
sample (``api.reconstruct(video, outline, frames="0:24")``, ``api.build_3d`` and
``api.build_tree(bpy.context, tree, "T")``), and asserts an armature with bones and keyframes.
``--site DIR`` also asserts scipy and cv2 were imported from DIR (the wheels).
Exits 0 on success, 1 on any failure.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import time
import traceback


def _args() -> argparse.Namespace:
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    ap = argparse.ArgumentParser(prog="extension_check")
    where = ap.add_mutually_exclusive_group(required=True)
    where.add_argument("--module", help="installed extension module, e.g. bl_ext.user_default.tree_from_video")
    where.add_argument("--package-dir", help="the add-on folder extracted from the zip (bpy wheel mode)")
    ap.add_argument("--sample", required=True, help="folder with video.mp4 and outline.json")
    ap.add_argument("--frames", default="0:24")
    ap.add_argument("--site", help="assert scipy and cv2 come from this folder")
    return ap.parse_args(argv)


def _origin(mod) -> str:
    return f"{getattr(mod, '__version__', '?')} from {os.path.dirname(os.path.abspath(mod.__file__))}"


def main() -> int:
    a = _args()
    import bpy
    import numpy

    print(f"extension_check: Blender {bpy.app.version_string}, Python {sys.version.split()[0]}, "
          f"numpy {_origin(numpy)}", flush=True)
    if a.module:
        import addon_utils
        name = a.module
        if name not in bpy.context.preferences.addons:
            print(f"extension_check: {name} is not enabled; enabled: "
                  f"{sorted(bpy.context.preferences.addons.keys())}", file=sys.stderr)
            return 1
        loaded_default, loaded_state = addon_utils.check(name)
        if not loaded_state:
            print(f"extension_check: {name} is enabled in the preferences but did not load", file=sys.stderr)
            return 1
        pkg = importlib.import_module(name)
    else:
        pkg_dir = os.path.abspath(a.package_dir)
        name = os.path.basename(pkg_dir)
        sys.path.insert(0, os.path.dirname(pkg_dir))
        pkg = importlib.import_module(name)
        pkg.register()
    print(f"extension_check: add-on {name} loaded from {os.path.dirname(pkg.__file__)}", flush=True)

    import cv2
    import scipy
    print(f"extension_check: scipy {_origin(scipy)}", flush=True)
    print(f"extension_check: cv2 {_origin(cv2)}", flush=True)
    if a.site:
        site = os.path.realpath(a.site)
        for mod in (scipy, cv2):
            if not os.path.realpath(mod.__file__).startswith(site + os.sep):
                print(f"extension_check: {mod.__name__} was not imported from {site}", file=sys.stderr)
                return 1

    api = pkg.api                          # the public scripting API, as a user script reaches it
    library = api.species_library()
    assert {"broad", "sparse", "conifer", "palm"} <= set(library), f"species library incomplete: {sorted(library)}"

    sample = os.path.abspath(a.sample)
    t = time.perf_counter()
    res = api.reconstruct(os.path.join(sample, "video.mp4"), os.path.join(sample, "outline.json"), frames=a.frames)
    t_run = time.perf_counter() - t
    t = time.perf_counter()
    tree = api.build_3d(res, frames=a.frames)
    t_3d = time.perf_counter() - t
    t = time.perf_counter()
    out = api.build_tree(bpy.context, tree, "T")
    t_build = time.perf_counter() - t
    action_api = pkg.operators.scene.action_api       # loaded by build_tree

    rig = out["armature"]
    assert rig is not None and rig.type == "ARMATURE", f"no armature: {rig!r}"
    n_bones = len(rig.data.bones)
    action = rig.animation_data.action if rig.animation_data else None
    assert action is not None, "the armature has no action"
    fcurves = list(action_api.action_fcurves(action))
    n_keys = sum(len(fc.keyframe_points) for fc in fcurves)
    assert n_bones > 0, "the armature has no bones"
    assert n_keys > 0, "the action has no keyframes"
    n_leaves = tree.leaves.count if tree.leaves is not None else 0
    assert n_leaves > 0, "the reconstruction has no leaf clusters"
    assert n_bones == len(tree.edges()) + n_leaves, \
        f"{n_bones} bones for {len(tree.edges())} skeleton edges + {n_leaves} leaf clusters"
    assert out["leaves"] is not None and out["leaves"].data.shape_keys is not None, "no leaf mesh with its flap keys"
    print(f"extension_check: OK: {len(tree.parents)} nodes x {tree.n_frames} frames -> armature "
          f"'{rig.name}' with {n_bones} bones ({n_leaves} leaf clusters), {len(fcurves)} F-curves, {n_keys} keys "
          f"(run {t_run:.1f} s, build_3d {t_3d:.1f} s, build_tree {t_build:.2f} s)", flush=True)
    return 0


if __name__ == "__main__":
    try:
        code = main()
    except Exception:
        traceback.print_exc()
        code = 1
    sys.stdout.flush()
    sys.exit(code)
