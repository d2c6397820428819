"""Batch entry: video + outline → moving 2D skeleton → animated 3D tree (+ Blender scene, exports).

    python batch.py VIDEO --outline OUTLINE.json|MASK.png --out DIR [options]
    python batch.py --generate N --species broad|FILE.json --out DIR [--envelope heart] [options]
    python batch.py VIDEO --outline ... --generate N --out DIR [options]    # species fitted from the video
    blender -b --python batch.py -- VIDEO --outline ... --out DIR [options]

Exit codes: 0 success, 2 bad input (one line on stderr naming the problem and the fix),
1 internal error. Progress lines go to stderr.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time
import traceback

PACKAGE = "tree_from_video"


def _package():
    """The extension package: the one this module belongs to (installed extension, e.g.
    ``bl_ext.user_default.tree_from_video``), else this folder loaded as ``tree_from_video``."""
    if __package__:
        return sys.modules[__package__]
    if PACKAGE in sys.modules:
        return sys.modules[PACKAGE]
    here = os.path.dirname(os.path.abspath(__file__))
    spec = importlib.util.spec_from_file_location(PACKAGE, os.path.join(here, "__init__.py"),
                                                  submodule_search_locations=[here])
    mod = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE] = mod
    spec.loader.exec_module(mod)
    return mod


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2
        sys.stderr.write(f"error: {message}; see --help\n")
        sys.exit(2)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="batch.py", description="Reconstruct a moving tree skeleton from a video, "
                "and/or generate new animated trees of a species (--generate).", epilog=GENERATE_HELP,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("video", nargs="?", help="input video file (mp4/mov/avi); optional with --generate --species")
    p.add_argument("--outline",
                   help="(required with a VIDEO) tree outline in frame 1: JSON list of [x, y] pixel points, a mask image (white = tree), "
                        "or 'auto' (what sways in the first seconds)")
    p.add_argument("--out", required=True, help="output folder (created if missing)")
    p.add_argument("--npz", action="store_true",
                   help="also write DIR/result.npz: parents (N,), nodes2d (F, N, 2) px, nodes3d (F, N, 3) m, level (N,), fps")
    p.add_argument("--levels", type=int, default=6, help="hierarchy levels incl. the root, 2..9 (default 6; paper: 5-7)")
    p.add_argument("--frames", default=None, metavar="A:B",
                   help="frame range, 0-based, B exclusive; either side may be empty (default: all)")
    p.add_argument("--skeleton", choices=("traced", "paper"), default="traced",
                   help="traced: branches traced in the video (default); paper: cluster centroids folded toward parents")
    p.add_argument("--scale", type=float, default=1.0, help="downscale the video by this factor (0 < s <= 1) for speed")
    p.add_argument("--conifer", action="store_true", help="conifer: keep the straight central leader fixed in the 3D lift")
    p.add_argument("--solver", choices=("probabilistic", "deterministic"), default="probabilistic",
                   help="3D motion solver (default probabilistic, paper §4; deterministic: sphere/line-of-sight baseline)")
    p.add_argument("--height", type=float, default=10.0, help="tree height in the scene, metres (default 10)")
    p.add_argument("--twigs", type=int, default=2, metavar="DEPTH",
                   help="generations of twigs copied from the tree's own forks, 0..6 (default 2; 0: none)")
    p.add_argument("--no-branch-fit", action="store_true",
                   help="pipe-model radii where they are traced, instead of widths and centre lines measured in frame 1")
    p.add_argument("--curliness", type=float, default=0.3,
                   help="bend the branch tubes along minimum-jerk curves, 0..1 (default 0.3; 0: straight)")
    p.add_argument("--bark", choices=("none", "smooth", "rough"), default="rough",
                   help="bark relief on the tubes: smooth (<= 0.5%% of the radius) or rough (1-5%%) (default rough)")
    p.add_argument("--no-leaves", action="store_true", help="bare branches: no leaf clusters")
    p.add_argument("--leaf-density", type=float, default=1.0,
                   help="share of the leaf seeds kept, (0, 1] (default 1): fewer, larger clusters, fewer polygons")
    p.add_argument("--leaf-cards", type=int, default=16, help="leaf cards (quads) per cluster (default 16)")
    p.add_argument("--flutter-hz", type=float, default=2.0, help="leaf flutter frequency in Hz (default 2)")
    p.add_argument("--leaf-image", help="image of one leaf (alpha = shape) instead of the procedural leaf")
    p.add_argument("--fbx", action="store_true", help="write DIR/tree.fbx (armature + skinned mesh, baked animation)")
    p.add_argument("--usd", action="store_true", help="write DIR/tree.usdc (needs a Blender built with USD)")
    p.add_argument("--gltf", action="store_true", help="write DIR/tree.glb (glTF binary, animation from t = 0)")
    p.add_argument("--blend", action="store_true", help="write DIR/tree.blend (the scene with the animated tree)")
    p.add_argument("--preview", action="store_true", help="write DIR/preview.png (front and side renders of frame 1)")
    p.add_argument("--no-video", action="store_true", help="skip overlay.mp4 (overlay.png is still written)")
    p.add_argument("--force", action="store_true", help="overwrite existing output files in DIR")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    g = p.add_argument_group("generation (--generate; see below)")
    g.add_argument("--generate", type=int, metavar="N", help="write N new animated trees (1..1000) to DIR/tree_000/ ...")
    g.add_argument("--species", help="species to grow without a video: broad, sparse, conifer (shipped) or a "
                                     "species .json file (with a VIDEO the species is fitted from its tree)")
    g.add_argument("--envelope", help="shape the trees fill: triangle, circle, pentagon, heart or a silhouette image "
                                      "(default: the video's outline; without a video circle, triangle for conifers)")
    g.add_argument("--wind", type=float, default=1.0, help="sway strength (default 1 = as in the example; 2 = twice)")
    g.add_argument("--audio", metavar="WAV", help="WAV recording whose loudness drives the sway over time (gusts)")
    g.add_argument("--seed", type=int, default=0, help="random seed; tree i uses seed + i (default 0)")
    g.add_argument("--nodes", type=int, default=200, help="node budget per tree (default 200)")
    g.add_argument("--frames-out", type=int, metavar="F",
                   help="frames of each generated animation (default: the species' source clip)")
    g.add_argument("--seconds", type=float, help="length of each generated animation in seconds (instead of --frames-out)")
    return p


GENERATE_HELP = """generation:
  --generate N writes DIR/generated.json (settings; per tree seed, species, envelope, bones,
  leaf clusters, files) and one folder per tree, DIR/tree_000/ ... DIR/tree_<N-1>/, each with
  tree3d.npz and the files asked for by --fbx/--usd/--gltf/--blend/--preview (tree.fbx, ...).
  With a VIDEO the reconstruction's files go to DIR as usual (without exports), plus
  DIR/species.json (the species fitted from the reconstructed tree). --height is the envelope's
  height in metres; --no-leaves/--leaf-density/--leaf-image apply to the generated trees."""


def _progress_printer(quiet: bool):
    last = {"stage": None, "t": 0.0}

    def cb(stage: str, frac: float):
        now = time.monotonic()
        if quiet or (stage == last["stage"] and now - last["t"] < 1.0 and frac < 1.0):
            return None
        last.update(stage=stage, t=now)
        sys.stderr.write(f"[{stage}] {100 * frac:3.0f}%\n")
        return None
    return cb


def _check_out(out: str, names: list[str], force: bool, InputError) -> None:
    if os.path.exists(out) and not os.path.isdir(out):
        raise InputError(f"--out '{out}' is a file; give a folder")
    parent = os.path.abspath(out)
    while not os.path.exists(parent):
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent) or not os.access(parent, os.W_OK):
        raise InputError(f"output folder '{out}' is not writable; choose another --out")
    existing = [n for n in names if os.path.exists(os.path.join(out, n))]
    if existing and not force:
        raise InputError(f"{os.path.join(out, existing[0])} exists; pass --force to overwrite or choose another --out")


def _blender_outputs(pkg, InputError):
    """The bpy side (operators/outputs.py), or a clear error when this Python has no Blender."""
    try:
        import bpy  # noqa: F401
    except ImportError:
        raise InputError("--fbx/--usd/--gltf/--blend/--preview need Blender's Python: run with the "
                         "project's venv (make setup) or as blender -b --python batch.py -- ...") from None
    from importlib import import_module
    return import_module(f"{pkg.__name__}.operators.outputs")


def _wanted(args) -> tuple[dict, list[str]]:
    """({format: bool}, file names) of the Blender exports asked for."""
    wanted = {"fbx": args.fbx, "usd": args.usd, "gltf": args.gltf, "blend": args.blend, "preview": args.preview}
    return wanted, [n for k, n in (("fbx", "tree.fbx"), ("usd", "tree.usdc"), ("gltf", "tree.glb"),
                                   ("blend", "tree.blend"), ("preview", "preview.png")) if wanted[k]]


def _plan_generation(args, pkg, InputError):
    """Check every --generate input before any work (core/generate_batch.py): the request, the
    species (mode without a video), the envelope, the audio. None without --generate."""
    if args.generate is None:
        if args.video is None:
            raise InputError("no VIDEO given: give VIDEO --outline OUTLINE.json, or --generate N --species NAME "
                             "to grow new trees")
        for opt in ("species", "envelope", "audio", "frames_out", "seconds"):
            if getattr(args, opt) is not None:
                raise InputError(f"--{opt.replace('_', '-')} only applies with --generate N; add it or drop the option")
        return None
    from importlib import import_module
    from types import SimpleNamespace
    gb = import_module(f"{pkg.__name__}.core.generate.batch")
    req = gb.GenerateRequest(count=args.generate, species=args.species, envelope=args.envelope, wind=args.wind,
                             audio=args.audio, seed=args.seed, nodes=args.nodes, frames_out=args.frames_out,
                             seconds=args.seconds, height_m=args.height,
                             leaf_density=0.0 if args.no_leaves else args.leaf_density)
    gb.check_request(req, has_video=args.video is not None)
    plan = SimpleNamespace(gb=gb, req=req, model=None, species_label=None, envelope=None, envelope_label=None)
    if req.species is not None:
        plan.model, plan.species_label = gb.load_species_spec(req.species)
    spec = req.envelope or (gb.default_envelope(plan.model) if plan.model is not None else None)
    if spec is not None:
        plan.envelope, plan.envelope_label = gb.make_envelope(spec, req.height_m)
    if req.audio is not None:
        gb.check_audio(req.audio)
    if args.leaf_image and not os.path.isfile(args.leaf_image):
        raise InputError(f"leaf image '{args.leaf_image}' does not exist; give an image file or drop "
                         "--leaf-image for the procedural leaf")
    return plan


def _run_generation(args, plan, outputs, wanted) -> int:
    """Grow and write the trees of ``plan`` (its model and envelope set) into ``args.out``."""
    log = (lambda m: None) if args.quiet else (lambda m: sys.stderr.write(m + "\n"))
    write = None
    if outputs is not None:
        def write(tree, folder):
            tree.meta["mesh"] = {"curliness": float(args.curliness), "bark": args.bark,     # the branch mesh's look
                                 "seed": int(tree.meta.get("seed", 0))}
            return outputs.write_outputs(tree, folder, wanted, overwrite=args.force, fresh_scene=True,
                                         report=log, leaf_image=args.leaf_image)
    t0 = time.monotonic()
    entries = plan.gb.generate_trees(plan.model, plan.species_label, plan.envelope, plan.envelope_label, plan.req,
                                     args.out, write, _progress_printer(args.quiet), log)
    bones = [e["bones"] for e in entries]
    sys.stderr.write(f"done: {len(entries)} tree(s) of {plan.species_label} in {plan.envelope_label}, "
                     f"{min(bones)}-{max(bones)} bones, {entries[0]['frames']} frames, "
                     f"{time.monotonic() - t0:.1f} s -> {os.path.join(args.out, plan.gb.INDEX)}\n")
    return 0


def _generate_only(args, pkg, plan, InputError) -> int:
    """``--generate N --species S`` without a video."""
    wanted, files = _wanted(args)
    _check_out(args.out, plan.gb.planned_files(plan.req, files), args.force, InputError)
    outputs = _blender_outputs(pkg, InputError) if files else None
    if outputs is not None:
        outputs.check_wanted(wanted)
    os.makedirs(args.out, exist_ok=True)
    return _run_generation(args, plan, outputs, wanted)


def _generate_from_tree(args, pkg, plan, tree, name, outputs, wanted) -> int:
    """``VIDEO --generate N``: fit the species of the reconstructed ``tree``, save DIR/species.json,
    grow the trees (default envelope: the reconstruction's)."""
    from importlib import import_module
    pgm = import_module(f"{pkg.__name__}.core.generate.species")
    lift3d = import_module(f"{pkg.__name__}.core.reconstruct.lift")
    plan.model = pgm.fit_species(plan.gb.without_twigs(tree), name)
    plan.species_label = os.path.join(args.out, plan.gb.SPECIES_FILE)
    pgm.save_species(plan.species_label, plan.model)
    if not args.quiet:
        sys.stderr.write(f"[species] {plan.species_label}\n")
    if plan.envelope is None:
        plan.envelope, plan.envelope_label = lift3d.envelope_from_meta(tree.meta), "reconstruction"
    return _run_generation(args, plan, outputs, wanted)


def main(argv: list[str] | None = None) -> int:
    """Run the batch job on ``argv``; returns the exit code (argparse errors exit 2 via SystemExit)."""
    args = build_parser().parse_args(argv)
    pkg = _package()
    from importlib import import_module
    errors = import_module(f"{pkg.__name__}.core.errors")
    try:
        gen = _plan_generation(args, pkg, errors.InputError)        # None without --generate
        if args.video is None:
            return _generate_only(args, pkg, gen, errors.InputError)
        if not args.outline:
            raise errors.InputError("give the tree's outline in frame 1 with --outline OUTLINE.json|MASK.png|auto")
        pipeline = import_module(f"{pkg.__name__}.core.pipeline")
        model = import_module(f"{pkg.__name__}.core.reconstruct.skeleton_io")
        overlay = import_module(f"{pkg.__name__}.core.reconstruct.overlay")
        wanted = {"fbx": args.fbx, "usd": args.usd, "gltf": args.gltf, "blend": args.blend,
                  "preview": args.preview}
        blender_files = [n for k, n in (("fbx", "tree.fbx"), ("usd", "tree.usdc"), ("gltf", "tree.glb"),
                                        ("blend", "tree.blend"), ("preview", "preview.png")) if wanted[k]]
        names = ["skeleton.npz", "tree3d.npz", "overlay.png"] + ([] if args.no_video else ["overlay.mp4"]) \
            + (["result.npz"] if args.npz else []) \
            + (blender_files if gen is None else gen.gb.planned_files(gen.req, blender_files, with_species=True))
        settings = pipeline.Settings(levels=args.levels, skeleton=args.skeleton, frames=args.frames,
                                     scale=args.scale, height_m=args.height)
        settings.lift.conifer = args.conifer
        settings.motion.solver = args.solver
        settings.twigs.depth = args.twigs
        settings.fit_branches = not args.no_branch_fit
        settings.curliness, settings.bark = args.curliness, args.bark
        if args.no_leaves:
            settings.leaves = None
        else:
            settings.leaves.density, settings.leaves.cards = args.leaf_density, args.leaf_cards
            settings.leaves.flutter_hz = args.flutter_hz
        if args.leaf_image and not os.path.isfile(args.leaf_image):
            raise errors.InputError(f"leaf image '{args.leaf_image}' does not exist; give an image file or drop "
                                    "--leaf-image for the procedural leaf")
        pipeline.check_settings(settings)
        _check_out(args.out, names, args.force, errors.InputError)
        outputs = _blender_outputs(pkg, errors.InputError) if blender_files else None
        if outputs is not None:
            outputs.check_wanted(wanted)
        cb = _progress_printer(args.quiet)
        res = pipeline.run(args.video, args.outline, settings, cb)
        os.makedirs(args.out, exist_ok=True)
        for w in res.warnings:
            sys.stderr.write(f"warning: {w}\n")
        meta = {"video": os.path.abspath(args.video), "frames": [res.start, res.stop],
                "levels": args.levels, "scale": args.scale, "version": getattr(pkg, "__version__", "")}
        model.save_skeleton(os.path.join(args.out, "skeleton.npz"), res.skeleton, meta)
        name = os.path.splitext(os.path.basename(args.video))[0] or "Tree"
        tree = pipeline.build_3d(res, settings, name=f"Tree {name}", progress=cb)
        tree.meta.update(meta)
        tree3d = import_module(f"{pkg.__name__}.core.tree3d")
        tree3d.save_tree(os.path.join(args.out, "tree3d.npz"), tree)
        if args.npz:
            arrays = model.skeleton_arrays(res.skeleton, meta)
            arrays["nodes3d"] = tree.nodes3d[:, :res.skeleton.n_nodes]     # twigs are appended after
            model.atomic_savez(os.path.join(args.out, "result.npz"), **arrays)
        overlay.write_overlays(res.info, res.start, res.skeleton, res.tracks,
                               os.path.join(args.out, "overlay.png"),
                               None if args.no_video else os.path.join(args.out, "overlay.mp4"), cb)
        if outputs is not None and gen is None:          # with --generate the exports are per generated tree
            outputs.write_outputs(tree, args.out, wanted, overwrite=args.force, leaf_image=args.leaf_image,
                                  report=lambda m: sys.stderr.write(m + "\n"))
        sys.stderr.write(f"done: {res.skeleton.n_nodes} nodes, {res.tracks.points.shape[1]} tracks, "
                         f"{res.tracks.n_frames} frames -> {args.out}\n")
        if gen is not None:
            return _generate_from_tree(args, pkg, gen, tree, name, outputs, wanted)
        return 0
    except errors.InputError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    except errors.Cancelled as exc:
        sys.stderr.write(f"cancelled: {exc}\n")
        return 1
    except Exception:  # internal error: keep the traceback for the bug report
        traceback.print_exc()
        sys.stderr.write("internal error: please report it with the traceback above\n")
        return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:] if "--" not in sys.argv else sys.argv[sys.argv.index("--") + 1:]))
