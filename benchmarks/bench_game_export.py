"""What a game engine gets (issue 33): one GLB per option for a reconstructed tree — every bone
and frame (the film asset), a 10 s seamless loop, a 64-bone rig, both, with three LODs, packed for
engines (core/asset/glb_pack.py, JPEG bark), with Pivot Painter's UVs — with its joints,
animation frames, size and export seconds, and the bone budget's vertex error. The
reconstruction is the ``long`` wind sample (480×360, 24 fps, 30 s; the product's look), its first
360 frames, reconstructed once into ``--work`` (not timed). bpy 5.0.1 wheel, 2 cores.

    .venv/bin/python benchmarks/bench_game_export.py [--work DIR] [--frames 360]
"""
from __future__ import annotations

import argparse
import json
import os
import struct
import tempfile
import time

from bench_blend_size import reconstructed

from _package import load_package


def glb_facts(path: str) -> tuple[int, int, float]:
    """(joints, animation keys per channel, MB) of a GLB."""
    data = open(path, "rb").read()
    n = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + n])
    anim = doc["animations"][0]
    keys = doc["accessors"][anim["samplers"][0]["input"]]["count"]
    return len(doc["skins"][0]["joints"]), keys, len(data) / 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "tree_bench_game"))
    ap.add_argument("--frames", type=int, default=360)
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    pkg = load_package()
    path = reconstructed(args.work, args.frames)
    pkg.register()
    import bpy

    from tree_from_video.core.loop import loop_tree
    from tree_from_video.core.tree3d import load_tree
    from tree_from_video.operators.scene import build, export, trees
    tree = load_tree(path)
    rows = []
    for label, loop_s, bones, lods, game in (
            ("film asset: every bone and frame", 0.0, None, 1, False), ("10 s loop", 10.0, None, 1, False),
            ("64 bones", 0.0, 64, 1, False), ("64 bones, 10 s loop", 10.0, 64, 1, False),
            ("64 bones, 10 s loop, LOD0..2", 10.0, 64, 3, False),
            ("the same, packed for engines (game GLB)", 10.0, 64, 3, True),
            ("the same with Pivot Painter UVs (--engine unreal's GLB)", 10.0, 64, 3, "pp2")):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        t = loop_tree(tree, loop_s)[0] if loop_s else tree
        built = build.build_tree(bpy.context, t, "Tree", bone_budget=bones, lods=lods, pivots=game == "pp2")
        out = os.path.join(args.work, f"game_{len(rows)}.glb")
        t0 = time.perf_counter()
        export.export_gltf(out, trees.tree_objects(built["collection"]), overwrite=True, game=bool(game))
        seconds = time.perf_counter() - t0
        joints, keys, mb = glb_facts(out)
        err = built["budget"].line() if built["budget"] is not None else "—"
        rows.append((label, joints, keys, mb, seconds, err))
    print(f"\nthe long sample reconstructed ({tree.n_frames} frames, {tree.n_nodes - 1} branch bones, "
          f"{tree.leaves.count if tree.leaves is not None else 0} leaf clusters), one GLB per option")
    print("| GLB | joints | keys per channel | MB | export s | bone budget's vertex error |")
    print("|---|---|---|---|---|---|")
    for label, joints, keys, mb, seconds, err in rows:
        print(f"| {label} | {joints} | {keys} | {mb:.1f} | {seconds:.1f} | {err} |")


if __name__ == "__main__":
    main()
