"""Exports at production scale (issue 32): one reconstructed tree exported to FBX and glTF alone in
the file, then again beside the panel's default forest (12 generated trees) — the target is the
same time within 20 % — and every forest tree exported, the time per tree and in all (target
≤ 60 s for the 12 on 2 cores). Each export runs in a scene of its own holding only its tree
(``operators/scene/export.py``); ``--user-scene`` times the way it was (the exporters evaluating
the user's scene, every tree of it, at every frame) for the before column.

The tree is ``sample_videos/broad`` reconstructed over its 180 frames with the product's look
(``DIR/tree3d.npz`` is reused). bpy 5.0.1 wheel; nothing else may run beside it (2 cores).

    .venv/bin/python benchmarks/bench_export.py [--work DIR] [--user-scene]
"""
from __future__ import annotations

import argparse
import contextlib
import os
import subprocess
import sys
import tempfile
import time

from _package import ROOT, load_package

TARGET_RATIO = 1.2
TARGET_FOREST_S = 60.0


def reconstructed(work: str) -> str:
    path = os.path.join(work, "broad", "tree3d.npz")
    if not os.path.exists(path):
        folder = os.path.join(ROOT, "sample_videos", "broad")
        subprocess.run([sys.executable, os.path.join(ROOT, "batch.py"), os.path.join(folder, "video.mp4"),
                        "--outline", os.path.join(folder, "outline.json"), "--out", os.path.dirname(path),
                        "--no-video", "--quiet", "--force"], check=True)
    return path


def objects(coll) -> list:
    return [ob for ob in coll.all_objects if ob.type in ("ARMATURE", "MESH")]


def timed_export(fmt: str, objs, path: str) -> float:
    from tree_from_video.operators.scene import export
    t = time.perf_counter()
    (export.export_fbx if fmt == "FBX" else export.export_gltf)(path, objs, overwrite=True)
    return time.perf_counter() - t


@contextlib.contextmanager
def in_user_scene(enabled: bool):
    """With ``enabled``, the exporters run in the user's scene (the code before issue 32)."""
    from tree_from_video.operators.scene import export
    if not enabled:
        yield
        return
    original = export._own_scene

    @contextlib.contextmanager
    def user_scene(context, objects):
        yield context
    export._own_scene = user_scene
    try:
        yield
    finally:
        export._own_scene = original


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "tree_bench_export"))
    ap.add_argument("--user-scene", action="store_true", help="export in the user's scene (before)")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    path = reconstructed(args.work)
    pkg = load_package()
    pkg.register()
    import bpy

    from tree_from_video.core.tree3d import load_tree
    from tree_from_video.operators.scene import build
    bpy.ops.wm.read_factory_settings(use_empty=True)
    tree = load_tree(path)
    recon = build.build_tree(bpy.context, tree, "Reconstruction")
    objs = objects(recon["collection"])
    label = "user's scene (before)" if args.user_scene else "own scene (now)"
    with in_user_scene(args.user_scene):
        alone = {fmt: timed_export(fmt, objs, os.path.join(args.work, f"alone.{fmt.lower()}")) for fmt in ("FBX", "GLB")}
        assert bpy.ops.tree_video.generate_forest() == {"FINISHED"}
        forest = [c for c in bpy.data.collections if c.name.startswith("Forest ")]
        crowd = {fmt: timed_export(fmt, objs, os.path.join(args.work, f"crowd.{fmt.lower()}")) for fmt in ("FBX", "GLB")}
        per_tree = [timed_export("GLB", objects(c), os.path.join(args.work, f"forest_{k:02d}.glb"))
                    for k, c in enumerate(forest)]
    print(f"\nexports in the {label}: the broad reconstruction ({tree.n_frames} frames, "
          f"{tree.n_nodes - 1} bones + {tree.leaves.count if tree.leaves is not None else 0} leaf clusters)")
    print("| export | alone | beside a 12-tree forest | ratio (target ≤ 1.2) |")
    print("|---|---|---|---|")
    for fmt in ("FBX", "GLB"):
        print(f"| {fmt} | {alone[fmt]:.2f} s | {crowd[fmt]:.2f} s | {crowd[fmt] / alone[fmt]:.2f} |")
    total = sum(per_tree)
    print(f"| the forest's {len(per_tree)} trees, GLB each | {min(per_tree):.2f}–{max(per_tree):.2f} s a tree | "
          f"{total:.1f} s in all | {total / TARGET_FOREST_S:.2f} × the 60 s target |")


if __name__ == "__main__":
    main()
