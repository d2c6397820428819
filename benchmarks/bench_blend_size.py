"""The .blend an artist gets (issue 32): a reconstructed tree of 555 frames and the default 12-tree
forest at 180 frames, built as before (a LINEAR key per bone, channel and frame: ``every_key``) and
as now (core/keys.py: Bezier keys where the motion needs them, baked samples where it jitters,
the leaves' flutter one cycle); the forest also with every tree its own (*Variants* 0) and with the
panel's default variants, each built once and standing again as instances sharing its data and
motion (operators/scene/instances.py). For each it prints the F-curves' keys and samples, the largest
node error of the curves over every frame against the model (share of the tree height), the
.blend's size saved as Blender saves by default (uncompressed) and with *Compress* (as the batch's
``--blend`` writes it), and the peak memory of a background Blender (the bpy wheel: 256 MB with an
empty file) opening the uncompressed one.

The reconstruction is the ``long`` wind sample (480×360, 24 fps, 30 s) over its first 555 frames,
generated and reconstructed once into ``--work`` (not timed).

    .venv/bin/python benchmarks/bench_blend_size.py [--work DIR] [--frames 555] [--only tree,forest]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

from _package import ROOT, load_package

TARGET_TREE_MB = 10.0
TARGET_FOREST_MB = 60.0
TARGET_OPEN_MB = 1024.0


def reconstructed(work: str, frames: int) -> str:
    """``work/long_<frames>/tree3d.npz``: the long sample reconstructed with the product's look."""
    out = os.path.join(work, f"long_{frames}")
    path = os.path.join(out, "tree3d.npz")
    if os.path.exists(path):
        return path
    from tree_from_video.sample_videos import synth_tree
    clip = os.path.join(work, "long_clip")
    if not os.path.exists(os.path.join(clip, "video.mp4")):
        synth_tree.generate(synth_tree.config_for("long", seed=0), clip)
    subprocess.run([sys.executable, os.path.join(ROOT, "batch.py"), os.path.join(clip, "video.mp4"),
                    "--outline", os.path.join(clip, "outline.json"), "--out", out, "--frames", f"0:{frames}",
                    "--no-video", "--quiet", "--force"], check=True)
    return path


def curves_count():
    import bpy

    from tree_from_video.operators.scene.action_api import action_fcurves
    curves = [fc for a in bpy.data.actions for fc in action_fcurves(a)]
    return len(curves), sum(len(fc.keyframe_points) for fc in curves), sum(len(fc.sampled_points) for fc in curves)


def node_error(built: list[dict], trees) -> float:
    """Largest node error over every frame of the built rigs against their trees, share of height."""
    import bpy

    from tree_from_video.core import bones
    worst = 0.0
    scene = bpy.context.scene
    for res, tree in zip(built, trees):
        rig = res["armature"]
        names = bones.bone_names(tree.parents)
        child = bones.bone_edges(tree.parents)[:, 1]
        H = float(np.ptp(tree.nodes3d[0][:, 2]))
        mw = np.array(rig.matrix_world)
        for f in range(1, tree.n_frames + 1):
            scene.frame_set(f)
            tails = np.array([rig.pose.bones[n].tail for n in names]) @ mw[:3, :3].T + mw[:3, 3]
            want = tree.nodes3d[f - 1][child].astype(np.float64) + mw[:3, 3]
            worst = max(worst, float(np.abs(tails - want).max()) / H)
    return worst


def open_peak_mb(path: str) -> float:
    """Peak RSS (MB) of a fresh Python with the bpy wheel opening ``path`` in the background."""
    # VmHWM (not ru_maxrss, which on Linux keeps the forking parent's high-water mark across exec)
    code = (f"import bpy; bpy.ops.wm.open_mainfile(filepath={path!r}); "
            "print('peak', [l.split()[1] for l in open('/proc/self/status') if l.startswith('VmHWM')][0])")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout
    return float(out.rsplit("peak", 1)[1].split()[0]) / 1024.0


def saved(folder: str, name: str) -> tuple[float, float, float]:
    """(.blend MB uncompressed, MB compressed, peak MB to open the uncompressed one)."""
    import bpy
    plain = os.path.join(folder, name + ".blend")
    packed = os.path.join(folder, name + "_z.blend")
    bpy.ops.wm.save_as_mainfile(filepath=plain, copy=True, compress=False)
    bpy.ops.wm.save_as_mainfile(filepath=packed, copy=True, compress=True)
    return os.path.getsize(plain) / 1e6, os.path.getsize(packed) / 1e6, open_peak_mb(plain)


def tree_case(path: str, every_key: bool, folder: str) -> dict:
    import bpy

    from tree_from_video.core.tree3d import load_tree
    from tree_from_video.operators.scene import build
    bpy.ops.wm.read_factory_settings(use_empty=True)
    tree = load_tree(path)
    res = build.build_tree(bpy.context, tree, "Tree", every_key=every_key)
    n, k, s = curves_count()
    err = node_error([res], [tree])
    mb, zmb, peak = saved(folder, "tree_every" if every_key else "tree")
    return dict(what=f"tree {tree.n_frames} frames, {tree.n_nodes - 1} bones + "
                f"{tree.leaves.count if tree.leaves is not None else 0} leaf clusters",
                curves=n, keys=k, samples=s, err=err, mb=mb, zmb=zmb, peak=peak)


def forest_case(frames: int, every_key: bool, folder: str, variants: int | None = None) -> dict:
    import functools

    import bpy

    from tree_from_video.operators.scene import build
    from tree_from_video.operators.scene import forest as forest_build
    bpy.ops.wm.read_factory_settings(use_empty=True)
    props = bpy.context.scene.tree_video
    props.gen_frames = frames                             # the panel's other settings: its defaults
    if variants is not None:
        props.forest_variants = variants
    variants = props.forest_variants
    original = forest_build.build_tree
    if every_key:
        forest_build.build_tree = functools.partial(build.build_tree, every_key=True)
    try:
        assert bpy.ops.tree_video.generate_forest() == {"FINISHED"}
    finally:
        forest_build.build_tree = original
    n, k, s = curves_count()
    trees = len([o for o in bpy.data.objects if o.type == "ARMATURE"])
    mb, zmb, peak = saved(folder, f"forest_{'every' if every_key else 'keys'}_{variants}")
    kind = "every tree its own" if variants == 0 else f"{variants} variants"
    return dict(what=f"default forest: {trees} trees x {frames} frames, {kind}", curves=n, keys=k, samples=s,
                err=float("nan"), mb=mb, zmb=zmb, peak=peak)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "tree_blend_size"))
    ap.add_argument("--frames", type=int, default=555)
    ap.add_argument("--forest-frames", type=int, default=180)
    ap.add_argument("--only", default="tree,forest")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    pkg = load_package()
    pkg.register()
    only = set(args.only.split(","))
    rows = []
    if "tree" in only:
        path = reconstructed(args.work, args.frames)
        for every in (True, False):
            rows.append(("before" if every else "now", tree_case(path, every, args.work), TARGET_TREE_MB))
    if "forest" in only:
        for label, every, variants in (("before", True, 0), ("keys", False, 0), ("now", False, None)):
            rows.append((label, forest_case(args.forest_frames, every, args.work, variants), TARGET_FOREST_MB))
    print("\n| scene | keys | F-curves | keys | samples | node error / H | .blend MB | compressed MB "
          "(target) | peak MB to open |")
    print("|---|---|---|---|---|---|---|---|---|")
    for label, r, target in rows:
        err = "—" if not np.isfinite(r["err"]) else f"{r['err']:.3%}"
        print(f"| {r['what']} | {label} | {r['curves']:,} | {r['keys']:,} | {r['samples']:,} | {err} | "
              f"{r['mb']:.1f} | {r['zmb']:.1f} ({target:.0f}) | {r['peak']:.0f} |")


if __name__ == "__main__":
    main()
