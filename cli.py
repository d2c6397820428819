"""The batch job: video + outline → moving 2D skeleton → animated 3D tree (+ Blender scene, exports),
and new trees of a species (``--generate``).

    python batch.py VIDEO --outline OUTLINE.json|MASK.png --out DIR [options]
    python batch.py --generate N --species broad|FILE.json --out DIR [--envelope heart] [options]
    python batch.py VIDEO --outline ... --generate N --out DIR [options]    # species fitted from the video
    blender -b --python batch.py -- VIDEO --outline ... --out DIR [options]
    blender -c tree_from_video VIDEO --outline ... --out DIR [options]      # the installed extension

:func:`main` is what all of them call. Exit codes: 0 success, 2 bad input (one line on stderr
naming the problem and the fix), 1 internal error. Progress lines go to stderr. Defaults and
ranges of the options are the core's (:mod:`.core.params`).
"""
from __future__ import annotations

import argparse
import errno
import os
import sys
import tempfile
import time
import traceback
from types import SimpleNamespace

from . import __version__, api
from .core import pipeline
from .core.asset.game import ENGINES, GameSettings, preset
from .core.detail.branch_mesh import MeshParams
from .core.detail.leaf_clusters import LeafParams
from .core.detail.twigs import TwigParams
from .core.envelope import envelope_from_meta
from .core.errors import Cancelled, InputError
from .core.farm import identity
from .core.farm.report import JobRecord, read_report
from .core.fileio import atomic_savez, read_json
from .core.formats import FORMATS
from .core.generate import batch as gb
from .core.generate import species
from .core.generate.photo import PhotoMotion, check_photo, is_photo
from .core.loop import LoopSettings
from .core.params import check, spec
from .core.reconstruct import node_motion, overlay, skeleton_io
from .core.reconstruct.motion import MotionParams
from .core.reconstruct.run import ReconstructSettings
from .core.tree3d import save_tree


def _default(cls: type, name: str):
    return spec(cls, name).default


def _range(cls: type, name: str) -> str:
    return spec(cls, name).describe()


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2
        sys.stderr.write(f"error: {message}; see --help\n")
        sys.exit(2)


def build_parser() -> argparse.ArgumentParser:
    """The batch options; their defaults and ranges come from the core's parameter dataclasses."""
    R, S, M = ReconstructSettings, pipeline.Settings, MeshParams
    p = _Parser(prog="batch.py", description="Reconstruct a moving tree skeleton from a video, "
                "and/or generate new animated trees of a species (--generate).", epilog=GENERATE_HELP,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("video", nargs="?", help="input video file (mp4/mov/avi); optional with --generate --species")
    p.add_argument("--outline",
                   help="(required with a VIDEO) tree outline in frame 1: JSON list of [x, y] pixel points, a mask "
                        "image (white = tree), or 'auto' (what sways in the first seconds)")
    p.add_argument("--out", help="(required) output folder (created if missing); it gets report.json and job.log")
    p.add_argument("--tree", metavar="TREE3D.npz",
                   help="instead of a VIDEO: build the Blender outputs (--gltf, --fbx, ...) of a tree an earlier "
                        "job saved (its tree3d.npz), the exports step alone (a farm runs the video on any worker "
                        "and this on Blender workers)")
    p.add_argument("--job", metavar="JOB.json",
                   help="the job as a file: a JSON object of these options by name (video, outline, out, gltf, "
                        "bones, ...; true for a switch); only --force, --dry-run and --quiet may be added on the line")
    p.add_argument("--dry-run", action="store_true",
                   help="say whether the job would run, run again or be skipped (done), and do nothing")
    p.add_argument("--npz", action="store_true",
                   help="also write DIR/result.npz: parents (N,), nodes2d (F, N, 2) px, nodes3d (F, N, 3) m, "
                        "level (N,), fps")
    p.add_argument("--levels", type=int, default=_default(R, "levels"),
                   help=f"hierarchy levels incl. the root, {_range(R, 'levels')} (default %(default)s; paper: 5-7)")
    p.add_argument("--frames", default=None, metavar="A:B",
                   help="frame range, 0-based, B exclusive; either side may be empty (default: all)")
    p.add_argument("--skeleton", choices=spec(R, "skeleton").choices, default=_default(R, "skeleton"),
                   help="traced: branches traced in the video (default); paper: cluster centroids folded toward "
                        "parents")
    p.add_argument("--scale", type=float, default=_default(R, "scale"),
                   help=f"downscale the video by this factor, {_range(R, 'scale')}, for speed (default %(default)s)")
    p.add_argument("--form", choices=spec(R, "form").choices, default=_default(R, "form"),
                   help="the tree's form: auto (default: a crown narrowing to its top is a conifer, else a "
                        "broadleaf), broadleaf, conifer (a leader to the top with whorls, kept straight in the lift) "
                        "or palm (a trunk with a crown of fronds from its top)")
    p.add_argument("--conifer", action="store_true", help="the same as --form conifer")
    p.add_argument("--limbs", choices=spec(S, "limbs").choices, default=_default(S, "limbs"),
                   help="the crown's limbs: auto (default: traced, or grown from a species where no bark shows "
                        "in the crown), trace, or grow (a species' growth inside frame 1's tree pixels)")
    p.add_argument("--limb-species", default=S().limb_species, metavar="NAME|FILE.json",
                   help="the species grown for --limbs (a library name or a species file; default: the library's "
                        "species of the tree's form)")
    p.add_argument("--depth", choices=spec(S, "depth").choices, default=_default(S, "depth"),
                   help="where the 3D lift takes the depth one view cannot show: learned (default: a network "
                        "trained on synthetic trees predicts from frame 1 how far each branch and the crown reach "
                        "from the trunk's plane) or envelope (the outline turned about the trunk, as the paper)")
    p.add_argument("--solver", choices=spec(MotionParams, "solver").choices, default=_default(MotionParams, "solver"),
                   help="3D motion solver (default probabilistic, paper §4; deterministic: sphere/line-of-sight "
                        "baseline)")
    p.add_argument("--height", type=float, default=_default(S, "height_m"),
                   help=f"tree height in the scene, metres, {_range(S, 'height_m')} (default %(default)s)")
    p.add_argument("--twigs", type=int, default=_default(TwigParams, "depth"), metavar="DEPTH",
                   help=f"generations of twigs copied from the tree's own forks, {_range(TwigParams, 'depth')} "
                        "(default %(default)s; 0: none)")
    p.add_argument("--no-branch-fit", action="store_true",
                   help="pipe-model radii where they are traced, instead of widths and centre lines measured in "
                        "frame 1")
    p.add_argument("--curliness", type=float, default=_default(M, "curliness"),
                   help=f"bend the branch tubes along minimum-jerk curves, {_range(M, 'curliness')} "
                        "(default %(default)s; 0: straight)")
    p.add_argument("--bark", choices=spec(M, "bark").choices, default=_default(M, "bark"),
                   help="bark relief on the tubes: smooth (<= 0.5%% of the radius) or rough (1-5%%) "
                        "(default %(default)s)")
    p.add_argument("--no-leaves", action="store_true", help="bare branches: no leaf clusters")
    p.add_argument("--leaf-density", type=float, default=_default(LeafParams, "density"),
                   help=f"share of the leaf seeds kept, {_range(LeafParams, 'density')} (default %(default)s): "
                        "fewer, larger clusters, fewer polygons")
    p.add_argument("--leaf-cards", type=int, default=_default(LeafParams, "cards"),
                   help=f"leaf cards (quads) per cluster, {_range(LeafParams, 'cards')} (default %(default)s)")
    p.add_argument("--flutter-hz", type=float, default=_default(LeafParams, "flutter_hz"),
                   help="leaf flutter frequency in Hz (default %(default)s)")
    p.add_argument("--leaf-colour", default=_default(LeafParams, "colour"),
                   help="leaf colour: albedo (the video's foliage corrected for exposure and white balance; a "
                        "plausible green where the video shows a dark or backlit silhouette), video (the raw "
                        "sample) or #RRGGBB (default %(default)s)")
    p.add_argument("--leaf-image", help="image of one leaf (alpha = shape) instead of the procedural leaf")
    p.add_argument("--engine", choices=sorted(ENGINES), default=None,
                   help="a game engine's preset (what it reads, how it loops, its LODs and engine files): "
                        + "; ".join(f"{k}: {_describe_engine(k)}" for k in sorted(ENGINES))
                        + ". Options given on the line win over the preset's")
    p.add_argument("--loop", type=float, default=None, metavar="SECONDS",
                   help="cut the animation the Blender outputs carry to a seamless loop of about this many "
                        "seconds (a length past the clip's takes the whole clip, its seam blended; named "
                        "<tree>_loop so engines loop it); tree3d.npz keeps the whole motion (default: no loop, or the "
                        "--engine preset's)")
    p.add_argument("--bones", type=int, default=None, metavar="N",
                   help="a game rig of at most N bones in the Blender outputs (e.g. 16, 32, 64, 128): the trunk "
                        "and the bones that move the tree most kept, the rest (leaf clusters too) joined rigidly to "
                        "them, the motion re-fitted; the vertex error is printed (default: every bone)")
    p.add_argument("--lods", type=int, default=None, metavar="K",
                   help=f"K levels of detail in the Blender outputs, {_range(GameSettings, 'lods')}: meshes "
                        "<tree>_LOD0.. (about 100 %%, 40 %%, 15 %% of LOD0's triangles, then x0.4), the same rig and "
                        "motion, under a <tree>_LODGroup empty (an FBX LOD group; Unity groups by the suffix) "
                        "(default 1: the film meshes, or the --engine preset's)")
    p.add_argument("--pivot-painter", action="store_true", default=None,
                   help="write Unreal Pivot Painter 2 textures beside the exports (pivot_pos_index.exr, "
                        "xaxis_extent.png; each vertex's element in UV channel 1) and pivot_painter.json (the "
                        "measured motion as wind parameters per level)")
    p.add_argument("--collision", action="store_true", default=None,
                   help="collision capsules for the trunk and main limbs: meshes UCP_<tree>_NN in the FBX (Unreal's "
                        "convention) and collision.json (every capsule's ends and radius) beside the exports")
    p.add_argument("--impostor", action="store_true", default=None,
                   help="a hemi-octahedral impostor rendered in Blender (impostor_albedo.png, impostor_normal.png: "
                        "8x8 views; impostor.json: layout, view directions, bounds) and a crossed-billboard card "
                        "<tree>_LOD<k> as the last level of detail")
    p.add_argument("--bone-texture", action="store_true", default=None,
                   help="write the motion as a bone-animation texture beside the exports (bone_anim.exr: a row "
                        "a frame, each bone's head displacement and rotation; bone_anim.json: layout, bones, "
                        "bind pose, fps, loop)")
    p.add_argument("--viewer", action="store_true", default=None,
                   help="write viewer.html (and viewer/, three.js) beside the exports: plays tree.glb in a browser, "
                        "and from bone_anim.exr with --bone-texture; open it through a local server "
                        "(python -m http.server). Needs --gltf")
    for f in FORMATS:                      # the output formats' registry: --fbx --usd --gltf --blend --preview
        p.add_argument(f"--{f.flag}", action="store_true", help=f.help.format(file=f.file))
    p.add_argument("--no-video", action="store_true", help="skip overlay.mp4 (overlay.png is still written)")
    p.add_argument("--force", action="store_true",
                   help="overwrite existing output files in DIR; run a job again that report.json says is done")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    f = p.add_argument_group("farm (--farm: many jobs on a Dask cluster; see the README's Farm)")
    f.add_argument("--farm", metavar="FOLDER|LIST.txt|JOBS.json",
                   help="run a job per video of a folder (mp4, mov, m4v, avi, mkv, webm, mts; each video's outline "
                        "is <stem>.outline.json or <stem>.mask.png beside it, else --outline), per line of a list "
                        "file, or per object of a jobs .json, into DIR/<stem>/, with the other options given here; "
                        "writes DIR/farm.json. Exit 0 all done, 1 some failed")
    f.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler (tcp://host:8786) to send the jobs to (default: a local cluster)")
    f.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the local cluster (default: the machine's cores)")
    f.add_argument("--job-timeout", type=float, default=0.0, metavar="S",
                   help="kill a job after S seconds (it is run once more, then reported; default 0: no limit)")
    f.add_argument("--blender", metavar="PATH",
                   help="run each job as PATH -b --python batch.py -- ... (default: this Python)")
    G = gb.GenerateRequest
    g = p.add_argument_group("generation (--generate; see below)")
    g.add_argument("--generate", type=int, metavar="N",
                   help=f"write N new animated trees ({_range(G, 'count')}) to DIR/tree_000/ ...")
    g.add_argument("--species", help="species to grow without a video: broad, sparse, conifer (shipped) or a "
                                     "species .json file (with a VIDEO the species is fitted from its tree)")
    g.add_argument("--envelope", help="shape the trees fill: triangle, circle, pentagon, heart or a silhouette image "
                                      "(default: the video's outline; without a video circle, triangle for conifers)")
    g.add_argument("--wind", type=float, default=_default(G, "wind"),
                   help="sway strength (default %(default)s = as in the example; 2 = twice)")
    g.add_argument("--audio", metavar="WAV", help="WAV recording whose loudness drives the sway over time (gusts)")
    g.add_argument("--seed", type=int, default=_default(G, "seed"),
                   help="random seed; tree i uses seed + i (default %(default)s)")
    g.add_argument("--nodes", type=int, default=_default(G, "nodes"),
                   help="node budget per tree (default %(default)s)")
    g.add_argument("--frames-out", type=int, metavar="F",
                   help="frames of each generated animation (default: the species' source clip)")
    g.add_argument("--seconds", type=float,
                   help="length of each generated animation in seconds (instead of --frames-out)")
    return p


GENERATE_HELP = """generation:
  --generate N writes DIR/generated.json (settings; per tree seed, species, envelope, bones,
  leaf clusters, files) and one folder per tree, DIR/tree_000/ ... DIR/tree_<N-1>/, each with
  tree3d.npz and the files asked for by --fbx/--usd/--gltf/--blend/--preview (tree.fbx, ...).
  With a VIDEO the reconstruction's files go to DIR as usual (without exports), plus
  DIR/species.json (the species fitted from the reconstructed tree). --height is the envelope's
  height in metres; --twigs/--no-leaves/--leaf-density/--leaf-image apply to the generated trees."""


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


def _check_out(out: str, names: list[str], force: bool) -> None:
    """Refuse, before any work, an output folder that is a file, cannot be created or written, or
    holds one of ``names`` (without ``force``)."""
    if os.path.exists(out) and not os.path.isdir(out):
        raise InputError(f"--out '{out}' is a file; give a folder")
    parent = os.path.abspath(out)
    while not os.path.exists(parent):
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent) or not os.access(parent, os.W_OK):
        raise InputError(f"output folder '{out}' is not writable; choose another --out")
    try:                     # as root os.access says yes where makedirs fails (/proc, a read-only mount)
        os.rmdir(tempfile.mkdtemp(prefix=".tfv-probe-", dir=parent))
    except OSError as exc:
        raise InputError(f"output folder '{out}' cannot be created ({exc.strerror}); choose another --out") from None
    existing = [n for n in names if os.path.exists(os.path.join(out, n))]
    if existing and not force:
        raise InputError(f"{os.path.join(out, existing[0])} exists; pass --force to overwrite or choose another --out")


def _blender_outputs():
    """The bpy side (batch outputs and preview renders), or a clear error when this Python has no
    Blender."""
    try:
        import bpy  # noqa: F401
    except ImportError:
        raise InputError(f"{'/'.join('--' + f.flag for f in FORMATS)} need Blender's Python: run with the "
                         "project's venv (make setup) or as blender -b --python batch.py -- ...") from None
    from .operators.scene import outputs
    return outputs


def _wanted(args) -> tuple[dict, list[str]]:
    """({format: bool}, file names) of the Blender exports asked for."""
    wanted = {f.flag: bool(getattr(args, f.flag)) for f in FORMATS}
    return wanted, [f.file for f in FORMATS if wanted[f.flag]]


def _describe_engine(engine: str) -> str:
    e = ENGINES[engine]
    files = [n for n in ("pivot_painter", "bone_texture", "collision", "impostor", "viewer") if e.get(n)]
    return (f"{'/'.join(e['formats'])}, {e['bones']} bones, {e['lods']} LOD(s), {e['loop_s']:g} s loop"
            + (f", {', '.join(files).replace('_', ' ')}" if files else ""))


def _apply_engine(args) -> None:
    """Fill the game options the line left out from the ``--engine`` preset (or the defaults), and
    the preset's export formats when no format flag is given."""
    if args.bones is not None and args.bones < 1:
        raise InputError(f"--bones {args.bones}: give at least 1 (e.g. 64), or drop it for every bone")
    game = preset(args.engine or "", bones=args.bones, lods=args.lods, loop_s=args.loop,
                  pivot_painter=args.pivot_painter, bone_texture=args.bone_texture, collision=args.collision,
                  viewer=args.viewer, impostor=args.impostor)
    args.bones = game.bones or None
    args.lods, args.loop = game.lods, game.loop_s
    args.pivot_painter, args.bone_texture = game.pivot_painter, game.bone_texture
    args.collision, args.viewer, args.impostor = game.collision, game.viewer, game.impostor
    if args.engine and not any(_wanted(args)[0].values()):
        for flag in game.formats:
            setattr(args, flag, True)


def _game(args) -> GameSettings:
    """The game export's settings of the command line (after :func:`_apply_engine`)."""
    return GameSettings(bones=args.bones or 0, lods=args.lods, pivot_painter=args.pivot_painter,
                        bone_texture=args.bone_texture, collision=args.collision, viewer=args.viewer,
                        impostor=args.impostor,
                        engine=args.engine or "", loop_s=args.loop)


def _check_loop(args) -> None:
    """--loop: a positive number of seconds, and --bones: at least 1; both for the Blender outputs."""
    if args.bones is not None and args.bones < 1:
        raise InputError(f"--bones {args.bones}: give at least 1 (e.g. 64), or drop it for every bone")
    if args.bones is not None and not any(_wanted(args)[0].values()):
        raise InputError("--bones cuts the rig of the Blender outputs; add one of "
                         f"{', '.join('--' + f.flag for f in FORMATS)}")
    if not spec(GameSettings, "lods").ok(args.lods):
        raise InputError(f"--lods {args.lods}: give a number of levels, {spec(GameSettings, 'lods').describe()}, e.g. 3")
    if args.viewer and not args.gltf:
        raise InputError("--viewer plays tree.glb; add --gltf (or use --engine web)")
    for on, flag in ((args.lods > 1, "--lods"), (args.pivot_painter, "--pivot-painter"),
                     (args.bone_texture, "--bone-texture"), (args.collision, "--collision"), (args.impostor, "--impostor"),
                     (args.viewer, "--viewer")):
        if on and not any(_wanted(args)[0].values()):
            raise InputError(f"{flag} comes with the Blender outputs; add one of "
                             f"{', '.join('--' + f.flag for f in FORMATS)}")
    if not spec(LoopSettings, "seconds").ok(args.loop):
        raise InputError(f"--loop {args.loop}: give a number of seconds, {spec(LoopSettings, 'seconds').describe()}, e.g. 10")
    if args.loop > 0 and not any(_wanted(args)[0].values()):
        raise InputError("--loop cuts the animation of the Blender outputs; add one of "
                         f"{', '.join('--' + f.flag for f in FORMATS)}")


def _check_leaf_image(path: str | None) -> None:
    if path and not os.path.isfile(path):
        raise InputError(f"leaf image '{path}' does not exist; give an image file or drop "
                         "--leaf-image for the procedural leaf")


def _plan_generation(args):
    """Check every --generate input before any work (:mod:`.core.generate.batch`): the request, the
    species (mode without a video), the envelope, the audio. None without --generate."""
    if args.generate is None:
        if args.video is None:
            raise InputError("no VIDEO given: give VIDEO --outline OUTLINE.json, or --generate N --species NAME "
                             "to grow new trees")
        photo_opts = ("species", "seconds") if is_photo(args.video) else ()     # a photo's sway
        for opt in ("species", "envelope", "audio", "frames_out", "seconds"):
            if getattr(args, opt) is not None and opt not in photo_opts:
                raise InputError(f"--{opt.replace('_', '-')} only applies with --generate N; add it or drop the option")
        return None
    req = gb.GenerateRequest(count=args.generate, species=args.species, envelope=args.envelope, wind=args.wind,
                             audio=args.audio, seed=args.seed, nodes=args.nodes, frames_out=args.frames_out,
                             seconds=args.seconds, height_m=args.height,
                             leaf_density=0.0 if args.no_leaves else args.leaf_density, twig_depth=args.twigs,
                             loop_s=args.loop)
    gb.check_request(req, has_video=args.video is not None)
    plan = SimpleNamespace(req=req, model=None, species_label=None, envelope=None, envelope_label=None)
    if req.species is not None:
        plan.model, plan.species_label = gb.load_species_spec(req.species)
    spec_ = req.envelope or (gb.default_envelope(plan.model) if plan.model is not None else None)
    if spec_ is not None:
        plan.envelope, plan.envelope_label = gb.make_envelope(spec_, req.height_m)
    if req.audio is not None:
        gb.check_audio(req.audio)
    _check_leaf_image(args.leaf_image)
    return plan


def _run_generation(args, plan, outputs, wanted) -> int:
    """Grow and write the trees of ``plan`` (its model and envelope set) into ``args.out``."""
    log = (lambda m: None) if args.quiet else (lambda m: sys.stderr.write(m + "\n"))
    write = None
    if outputs is not None:
        def write(tree, folder):
            tree.meta["mesh"] = {"curliness": float(args.curliness), "bark": args.bark,     # the branch mesh's look
                                 "seed": int(tree.meta.get("seed", 0))}
            return _write_blender(args, outputs, tree, folder, wanted, log)
    t0 = time.monotonic()
    entries = gb.generate_trees(plan.model, plan.species_label, plan.envelope, plan.envelope_label, plan.req,
                                args.out, write, args.record.timed(_progress_printer(args.quiet)), log)
    bones = [e["bones"] for e in entries]
    args.record.add(trees=len(entries), leaf_clusters=sum(e["leaf_clusters"] for e in entries))
    if "bones" not in args.record.counts:                  # the Blender outputs count the rig they built
        args.record.add(bones=sum(bones))
    sys.stderr.write(f"done: {len(entries)} tree(s) of {plan.species_label} in {plan.envelope_label}, "
                     f"{min(bones)}-{max(bones)} bones, {entries[0]['frames']} frames, "
                     f"{time.monotonic() - t0:.1f} s -> {os.path.join(args.out, gb.INDEX)}\n")
    return 0


def _generate_only(args, plan) -> int:
    """``--generate N --species S`` without a video."""
    wanted, files = _wanted(args)
    _check_out(args.out, gb.planned_files(plan.req, files), args.force)
    outputs = _blender_outputs() if files else None
    if outputs is not None:
        outputs.check_wanted(wanted)
    _begin(args)
    return _run_generation(args, plan, outputs, wanted)


def _generate_from_tree(args, plan, tree, name, outputs, wanted) -> int:
    """``VIDEO --generate N``: fit the species of the reconstructed ``tree``, save DIR/species.json,
    grow the trees (default envelope: the reconstruction's)."""
    plan.model = species.fit_species(tree, name)              # its branches: the twigs left out
    plan.species_label = os.path.join(args.out, gb.SPECIES_FILE)
    species.save_species(plan.species_label, plan.model)
    if not args.quiet:
        sys.stderr.write(f"[species] {plan.species_label}\n")
    if plan.envelope is None:
        plan.envelope, plan.envelope_label = envelope_from_meta(tree.meta), "reconstruction"
    return _run_generation(args, plan, outputs, wanted)


def settings_from_args(args) -> pipeline.Settings:
    """The :class:`~.core.pipeline.Settings` of a reconstruction asked for by ``args``, checked
    (:func:`.api.settings`: the same keywords a script passes)."""
    return api.settings(levels=args.levels, skeleton=args.skeleton, frames=args.frames, scale=args.scale,
                        height_m=args.height, form="conifer" if args.conifer else args.form, solver=args.solver, twigs=args.twigs,
                        fit_branches=not args.no_branch_fit, curliness=args.curliness, bark=args.bark,
                        leaves=not args.no_leaves, leaf_density=args.leaf_density, leaf_cards=args.leaf_cards,
                        flutter_hz=args.flutter_hz, leaf_colour=args.leaf_colour, limbs=args.limbs, depth=args.depth,
                        limb_species=args.limb_species)


#: the folder of tree k (1-based) when the outline holds several trees
TREE_FOLDER = "tree_{k}"


def _reconstruct(args, gen) -> int:
    """``VIDEO --outline ... --out DIR``: the reconstruction, its files and (with --generate) the trees.
    An outline of several trees (a .json of several polygons, a mask of several components) gives
    one folder ``DIR/tree_<k>/`` per tree, from one decode and one tracking pass."""
    if not args.outline:
        raise InputError("give the tree's outline in frame 1 with --outline OUTLINE.json|MASK.png|auto")
    wanted, blender_files = _wanted(args)
    names = ["skeleton.npz", "tree3d.npz", "overlay.png"] + ([] if args.no_video else ["overlay.mp4"]) \
        + (["result.npz"] if args.npz else []) \
        + (blender_files if gen is None else gb.planned_files(gen.req, blender_files, with_species=True))
    _check_leaf_image(args.leaf_image)
    settings = settings_from_args(args)
    photo = None
    if is_photo(args.video):            # one frame: the tree sways as its species (core/generate/photo.py)
        check_photo(args.video)
        photo = PhotoMotion(species=args.species or "",
                            seconds=PhotoMotion().seconds if args.seconds is None else args.seconds,
                            wind=args.wind, seed=args.seed)
        check(photo)                                   # --seconds and --wind within PhotoMotion's ranges
        if photo.species:
            gb.load_species_spec(photo.species)        # a missing or broken species file fails now
    n_trees = pipeline.count_outlines(args.video, args.outline, settings.scale, settings.frames)
    if n_trees > 1 and gen is not None:
        raise InputError(f"--generate grows trees of one reconstructed tree, and the outline holds {n_trees}; "
                         "give one outline")
    folders = [args.out] if n_trees == 1 else [os.path.join(args.out, TREE_FOLDER.format(k=k + 1))
                                               for k in range(n_trees)]
    for folder in folders:
        _check_out(folder, names, args.force)
    outputs = _blender_outputs() if blender_files else None
    if outputs is not None:
        outputs.check_wanted(wanted)
    _begin(args)
    cb = args.record.timed(_progress_printer(args.quiet))
    results = pipeline.run_all(args.video, args.outline, settings, cb)
    info = results[0].info
    args.record.video = {"width": info.width, "height": info.height, "fps": float(info.fps),
                         "frames": [int(results[0].start), int(results[0].stop)],
                         "time_base": "index / fps" if results[0].tracks.times is None else "frame timestamps"}
    base = os.path.splitext(os.path.basename(args.video))[0] or "Tree"
    names = [f"Tree {base}"] if n_trees == 1 else [f"Tree {base} {k + 1}" for k in range(n_trees)]
    trees = pipeline.build_shot(results, settings, names, cb, photo=photo)     # one scale, each where it stands
    for res, tree, folder in zip(results, trees, folders):
        _write_tree(args, res, tree, folder, outputs, wanted, gen is None, cb)
    if gen is not None:
        return _generate_from_tree(args, gen, trees[0], base, outputs, wanted)
    return 0


def _write_blender(args, outputs, tree, out: str, wanted: dict, report=None) -> dict:
    """The Blender outputs of ``tree`` in ``out`` with the line's look, loop and game options; the
    built rig's counts go to the job's record (every batch path writes them through here)."""
    return outputs.write_outputs(tree, out, wanted, overwrite=args.force, leaf_image=args.leaf_image,
                                 report=report or (lambda m: sys.stderr.write(m + "\n")), loop_s=args.loop,
                                 game=_game(args), stats=args.record.counts)


def _write_tree(args, res, tree, out: str, outputs, wanted, exports: bool, cb) -> None:
    """Write one reconstructed tree's files (its 2D result ``res``, its 3D ``tree``) into ``out``."""
    os.makedirs(out, exist_ok=True)
    for w in res.warnings:
        sys.stderr.write(f"warning: {w}\n")
        args.record.warn(w)
    args.record.add(trees=1, tracks=res.tracks.n_tracks, nodes=tree.n_nodes,
                    leaf_clusters=tree.leaves.count if tree.leaves is not None else 0)
    meta = {"video": os.path.abspath(args.video), "frames": [res.start, res.stop],
            "levels": args.levels, "scale": args.scale, "version": __version__}
    skeleton_io.save_skeleton(os.path.join(out, "skeleton.npz"), res.skeleton, meta)
    tree.meta.update(meta)
    save_tree(os.path.join(out, "tree3d.npz"), tree)
    if args.npz:
        arrays = skeleton_io.skeleton_arrays(res.skeleton, meta)
        arrays["nodes3d"] = tree.nodes3d[:, :res.skeleton.n_nodes]     # twigs are appended after
        atomic_savez(os.path.join(out, "result.npz"), **arrays)
    overlay.write_overlays(res.info, res.start, res.skeleton, res.tracks,
                           os.path.join(out, "overlay.png"),
                           None if args.no_video else os.path.join(out, "overlay.mp4"), cb,
                           res.foreground.mask if res.foreground is not None else None)
    if outputs is not None and exports:              # with --generate the exports are per generated tree
        cb("blender outputs", 0.0)
        _write_blender(args, outputs, tree, out, wanted)
    conf = res.skeleton.confidence
    sure = "" if conf is None else f", {node_motion.confidence_summary(conf)}"
    sys.stderr.write(f"done: {res.skeleton.n_nodes} nodes, {res.tracks.n_tracks} tracks, "
                     f"{res.tracks.n_frames} frames{sure} -> {out}\n")


#: the farm command's own options (never a job's)
FARM_OPTIONS = ("farm", "scheduler", "workers", "job_timeout", "blender")
#: options that are not the job's settings (where it goes, how it talks, what to do with a done one)
NOT_SETTINGS = ("out", "video", "outline", "tree", "job", "force", "quiet", "dry_run", "record", "begun") + FARM_OPTIONS
#: errors of the disk a job writes to: the user's to fix (exit 2), not ours
USERS_DISK = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG)
#: the options --job allows beside it on the line
BESIDE_JOB = ("job", "force", "quiet", "dry_run")


def job_argv(doc, path: str) -> list[str]:
    """The command line of a job file's JSON object (its keys are the batch options' names, ``-`` or
    ``_``; a switch takes true/false, a number a number, the rest a string); :class:`InputError`
    for anything else."""
    if not isinstance(doc, dict):
        raise InputError(f"{path} holds no JSON object; write the options as {{\"video\": ..., \"out\": ...}}")
    actions = {a.dest: a for a in build_parser()._actions if a.dest not in ("help", "job")}
    argv: list[str] = []
    for key, value in doc.items():
        dest = str(key).replace("-", "_")
        a = actions.get(dest)
        if a is None or dest in ("dry_run", "force", "quiet") + FARM_OPTIONS:
            raise InputError(f"unknown key '{key}' in {path}; use the batch options' names (video, outline, out, "
                             "gltf, bones, ...) and give --force/--dry-run/--quiet on the line")
        flag = a.option_strings[0] if a.option_strings else None
        switch = a.nargs == 0
        kind = bool if switch else (a.type or str)
        ok = (isinstance(value, bool) if kind is bool else
              isinstance(value, int) and not isinstance(value, bool) if kind is int else
              isinstance(value, (int, float)) and not isinstance(value, bool) if kind is float else
              isinstance(value, str))
        if value is None:
            continue
        if not ok:
            want = {bool: "true or false", int: "a whole number", float: "a number"}.get(kind, "a string")
            raise InputError(f"'{key}' in {path} is {json_type(value)}; give {want}")
        if flag is None:
            argv.insert(0, str(value))
        elif switch:
            argv += [flag] if value else []
        else:
            argv += [flag, str(value)]
    return argv


def json_type(value) -> str:
    return {bool: "true/false", int: "a number", float: "a number", str: "a string", list: "a list",
            dict: "an object"}.get(type(value), type(value).__name__)


def _args_from_job(args):
    """The options of ``args.job`` (the line may add only --force, --dry-run, --quiet)."""
    bare = vars(build_parser().parse_args(["--job", args.job]))
    extra = [k for k, v in bare.items() if k not in BESIDE_JOB and getattr(args, k) != v]
    if extra:
        raise InputError(f"--{extra[0].replace('_', '-')} given beside --job; put it in {args.job} instead")
    if not os.path.isfile(args.job):
        raise InputError(f"job file '{args.job}' does not exist; give the path of a JSON job file")
    doc = read_json(args.job, f"job file '{args.job}'", "write the job as one JSON object of batch options")
    new = build_parser().parse_args(job_argv(doc, args.job))
    new.force, new.quiet, new.dry_run = args.force, args.quiet, args.dry_run
    return new


def _record(args, argv: list[str]) -> JobRecord:
    """The job's record: its settings (the resolved options; where it reads and writes excepted) and
    input identity."""
    settings = {k: v for k, v in sorted(vars(args).items()) if k not in NOT_SETTINGS}
    if args.outline == "auto":
        settings["outline"] = "auto"
    return JobRecord(list(argv), settings, identity.settings_hash(settings), __version__,
                     input=identity.input_identity(args.video or args.tree, args.outline))


class _Tee:
    """stderr that also keeps its lines for job.log."""

    def __init__(self, stream, lines: list[str]):
        self._stream, self._lines = stream, lines

    def write(self, text: str) -> int:
        self._lines.append(text)
        return self._stream.write(text)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _exports_only(args) -> int:
    """``--tree DIR/tree3d.npz --out DIR2 --gltf ...``: the Blender outputs of a saved tree."""
    if args.video or args.outline or args.generate is not None:
        raise InputError("--tree builds the outputs of a saved tree; drop the VIDEO, --outline and --generate")
    if not os.path.isfile(args.tree):
        raise InputError(f"tree file '{args.tree}' does not exist; give a tree3d.npz an earlier job wrote")
    wanted, files = _wanted(args)
    if not files:
        raise InputError(f"--tree builds the Blender outputs; add one of {', '.join('--' + f.flag for f in FORMATS)}")
    _check_leaf_image(args.leaf_image)
    _check_out(args.out, files + _game(args).files(), args.force)
    outputs = _blender_outputs()
    outputs.check_wanted(wanted)
    tree = api.load_tree(args.tree)
    _begin(args)
    args.record.add(trees=1, nodes=tree.n_nodes, leaf_clusters=tree.leaves.count if tree.leaves is not None else 0)
    args.record.timed(None)("blender outputs", 0.0)
    _write_blender(args, outputs, tree, args.out, wanted)
    sys.stderr.write(f"done: the outputs of {args.tree} -> {args.out}\n")
    return 0


def _begin(args) -> None:
    """The work starts: the folder gets a ``running`` report (a killed run leaves it saying so)."""
    os.makedirs(args.out, exist_ok=True)
    args.record.write(args.out)
    args.begun = True


def _run(args) -> int:
    """The job of ``args`` (parsed, its engine preset applied, its record set), after the checks
    every job takes."""
    _check_loop(args)
    if args.tree:
        return _exports_only(args)
    gen = _plan_generation(args)        # None without --generate
    if args.video is None:
        return _generate_only(args, gen)
    return _reconstruct(args, gen)


def main(argv: list[str] | None = None) -> int:
    """Run the batch job on ``argv``; returns the exit code (argparse errors exit 2 via SystemExit).
    Every job that got as far as its folder leaves ``report.json`` and ``job.log`` there
    (:mod:`.core.farm.report`); a done job (its report ``ok``, the same settings and input) is
    skipped unless ``--force``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    lines: list[str] = []
    stderr = sys.stderr
    sys.stderr = _Tee(stderr, lines)
    args.begun, prior, status, message = False, None, "ok", None
    try:
        try:
            if args.farm:
                from . import cli_farm
                return cli_farm.main(args, argv, SimpleNamespace(build_parser=build_parser, job_argv=job_argv,
                                                                 _apply_engine=_apply_engine, _record=_record))
            if args.job:
                args = _args_from_job(args)
                args.begun = False
            if not args.out:
                parser.error("the following arguments are required: --out")
            _apply_engine(args)
            args.record = _record(args, argv)
            args.record.log = lines
            prior = read_report(args.out) if os.path.isdir(args.out) else None
            decision = identity.decide(prior, args.record.settings_sha256, args.record.input, args.force)
            if args.dry_run:
                print(f"{decision.action}: {args.out}: {decision.why}")
                return 0
            if decision.action == "skip":
                sys.stderr.write(f"skipped: {args.out}: {decision.why}\n")
                return 0
            if decision.action == "redo":
                args.force = True                 # the files there are our unfinished run's
            return _run(args)
        except InputError as exc:
            status, message = "bad_input", str(exc)
            sys.stderr.write(f"error: {exc}\n")
            return 2
        except OSError as exc:
            if exc.errno not in USERS_DISK:
                raise
            where = exc.filename or args.out
            status, message = "bad_input", (f"cannot write {where} ({exc.strerror}); free space on that disk or "
                                            "choose another --out")
            sys.stderr.write(f"error: {message}\n")
            return 2
        except Cancelled as exc:
            status, message = "cancelled", str(exc)
            sys.stderr.write(f"cancelled: {exc}\n")
            return 1
        except Exception as exc:  # internal error: keep the traceback for the bug report
            status, message = "error", f"{exc.__class__.__name__}: {exc}"
            traceback.print_exc()
            sys.stderr.write("internal error: please report it with the traceback above\n")
            return 1
    finally:
        sys.stderr = stderr
        _final_report(args, prior, status, message)


def _final_report(args, prior: dict | None, status: str, message: str | None) -> None:
    """Write the job's report unless it never reached its folder: a failure before the work
    started reports only into an existing folder that holds no finished job's report."""
    record = getattr(args, "record", None)
    if record is None or getattr(args, "dry_run", False) or not args.out:
        return
    if not args.begun and not (os.path.isdir(args.out) and (prior is None or prior.get("status") != "ok")):
        return
    if not args.begun and status == "ok":
        return                                    # skipped: the done job's report stays
    try:
        record.finish(status, message, args.out)
        record.write(args.out)
    except OSError as exc:                         # a full disk or a read-only folder: say it, keep the code
        if status == "ok" or exc.errno not in USERS_DISK:     # a full disk was the one line already
            sys.stderr.write(f"warning: report.json not written in {args.out} ({exc.strerror})\n")
