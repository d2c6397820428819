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
from dataclasses import dataclass
from types import SimpleNamespace

from . import __version__
from .core import jobs, pipeline
from .core.asset.game import ENGINES, GameSettings
from .core.detail.bark_photo import (
    BarkPhotoParams,
    bark_maps,
    bark_photo_files,
    read_bark_files,
    read_bark_photo,
    write_bark_files,
)
from .core.detail.bark_stereo import MIN_INLIERS
from .core.detail.branch_mesh import MeshParams
from .core.detail.leaf_clusters import LeafParams
from .core.detail.relief import RELIEF_RINGS, RELIEF_SIDES
from .core.detail.trunk_strip import VIDEO_BARK
from .core.detail.twigs import TwigParams
from .core.envelope import envelope_from_meta
from .core.errors import Cancelled, InputError
from .core.farm import identity
from .core.farm.report import JobRecord, read_report
from .core.fileio import atomic_savez, read_json
from .core.formats import FORMATS
from .core.generate import batch as gb
from .core.generate import species
from .core.generate.cuts import parse_cut_spec
from .core.generate.photo import check_photo
from .core.generate.variations import VariationParams
from .core.params import spec
from .core.reconstruct import node_motion, overlay, skeleton_io
from .core.reconstruct.lift import LiftParams
from .core.reconstruct.motion import MotionParams
from .core.reconstruct.run import ReconstructSettings
from .core.tree3d import load_tree, save_tree
from .core.tree_cut import load_cut


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
    Mo, Li = MotionParams, LiftParams
    p.add_argument("--fold-alpha", type=float, default=_default(R, "fold_alpha"),
                   help=f"--skeleton paper: share of the way each node moves toward its parent, "
                        f"{_range(R, 'fold_alpha')} (default %(default)s; paper 0.4)")
    p.add_argument("--candidates", type=int, default=_default(Li, "candidates"),
                   help=f"depths tried for each branch in the 3D lift, {_range(Li, 'candidates')} "
                        "(default %(default)s; paper: L)")
    p.add_argument("--sigma-track", type=float, default=_default(Mo, "sigma_track"),
                   help=f"how far a solved branch may stray from its tracked 2D position, share of the height, "
                        f"{_range(Mo, 'sigma_track')} (default %(default)s; paper: σ_track)")
    p.add_argument("--sigma-shape", type=float, default=_default(Mo, "sigma_shape"),
                   help=f"how far a branch's angle to its parent may drift from frame 1's at the trunk, radians, "
                        f"{_range(Mo, 'sigma_shape')} (default %(default)s; paper: σ_shape)")
    p.add_argument("--max-step", type=float, default=_default(Mo, "max_step"),
                   help=f"largest turn of a branch from one frame to the next, radians per axis, "
                        f"{_range(Mo, 'max_step')} (default %(default)s)")
    p.add_argument("--max-total", type=float, default=_default(Mo, "max_total"),
                   help=f"largest total turn of a branch from its frame-1 pose, radians, {_range(Mo, 'max_total')} "
                        "(default %(default).4g; paper: Δ)")
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
    p.add_argument("--forks", choices=spec(M, "forks").choices, default=_default(M, "forks"),
                   help="where branches fork: joined (one closed surface, the continuing branch at the pipe "
                        "model's radius) or overlap (tubes that run into their parent) (default %(default)s)")
    p.add_argument("--bark-relief", type=float, default=_default(M, "relief_cm"), metavar="CM",
                   help=f"the bark's height map as geometry on the tubes, its depth on the trunk in cm, "
                        f"{_range(M, 'relief_cm')} (default %(default)s: none); the tubes get at least {RELIEF_SIDES} "
                        f"sides and {RELIEF_RINGS} rings a bone, LOD1+ keep none")
    B = BarkPhotoParams
    p.add_argument("--bark-image", action="append", metavar="PHOTO",
                   help="a close-up photo of the bark, or a folder of them (repeat for several): the bark "
                        "becomes a seamless tile quilted from it (albedo, height, normal and roughness maps, "
                        "DIR/bark_*.png), in the Blender outputs and every export, instead of the procedural "
                        "bark; photos of the same bark a step apart give its height by their parallax; "
                        "'video': the reconstructed trunk's own pixels in frame 1")
    p.add_argument("--moss", type=float, default=None,
                   help=f"moss found in the bark photo (green), {_range(B, 'moss')}: 0 removes it, 1 as "
                        f"photographed, 2 doubles its cover, crevices first (default {_default(B, 'moss'):g})")
    p.add_argument("--lichen", type=float, default=None,
                   help=f"lichen found in the bark photo (pale grey, bright yellow), {_range(B, 'lichen')}, as "
                        f"--moss (default {_default(B, 'lichen'):g})")
    p.add_argument("--bark-scale", type=float, default=None, metavar="CM",
                   help=f"how much bark one tile shows on the tree, cm, {_range(B, 'scale_cm')} "
                        f"(default {_default(B, 'scale_cm'):g})")
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
    p.add_argument("--flutter-gain", type=float, default=_default(LeafParams, "flutter_gain"),
                   help=f"leaf flutter strength per unit of branch speed, s, {_range(LeafParams, 'flutter_gain')} "
                        "(default %(default)s)")
    p.add_argument("--max-leaf-clusters", type=int, default=_default(LeafParams, "max_clusters"),
                   help=f"at most this many leaf clusters, {_range(LeafParams, 'max_clusters')} (default %(default)s)")
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
    p.add_argument("--billboard", type=int, metavar="PX",
                   help="the tree's front at rest rendered in Blender, PX pixels on its longer side: billboard.png "
                        "(RGBA, alpha the silhouette), billboard_normal.png (glTF-axes normals), billboard.json "
                        "(scale, where the tree stands); --generate writes one per tree; usable as --exemplars")
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
    g.add_argument("--envelope-variation", type=float, metavar="V",
                   help=f"each tree grows in its own crown around the envelope, {_range(G, 'envelope_variation')}: "
                        "its contour mixed V of the way toward the species' and the library's crown contours (seed "
                        "000's contour space), its leaf colour likewise within the species' range (default "
                        f"{_default(G, 'envelope_variation'):g}: the envelope as given)")
    g.add_argument("--allometry", action="store_true", default=None,
                   help="turn each fork's two children together so the thicker bends less, by Holton's rule "
                        "(a1 = a d2^2 / (d1^2 + d2^2), seed 001), within the envelope; broadleaf trees (it moves "
                        "the species' measured split of the fork angle)")
    g.add_argument("--cut", action="append", metavar="FILE[@X,Y,Z]",
                   help="a tree-cut every tree must contain (a .npz saved by the panel's Save Cut): placed where its "
                        "base's radius fits, or with @X,Y,Z its base on the branch nearest that point (metres from the "
                        "tree's base; x right, y depth, z up); the tree's branches in its way are grown elsewhere. "
                        "Repeat for several")
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
    V = VariationParams
    v = p.add_argument_group("tree variations (--variations; seed 000)")
    v.add_argument("--variations", type=int, metavar="N",
                   help=f"write N new RGBA tree images ({_range(V, 'count')}) made from --exemplars: their contours "
                        "combined, their colour carried into the new contour (DIR/variation_000.png ..., "
                        "DIR/variations.json); --seed draws them")
    v.add_argument("--exemplars", nargs="+", action="extend", metavar="IMAGE",
                   help="RGBA pictures of trees (transparent around the tree, e.g. a billboard) the variations "
                        "are made from; one is given its mirror image as a second")
    v.add_argument("--exemplar-outlines", nargs="+", action="extend", metavar="OUTLINE",
                   help="one per exemplar, in order: a photo's outline (polygon .json or mask image) that cuts "
                        "the tree out of it (its pixels against the sky around it), or '-' for an RGBA exemplar")
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


def _describe_engine(engine: str) -> str:
    e = ENGINES[engine]
    files = [n for n in ("pivot_painter", "bone_texture", "collision", "impostor", "viewer") if e.get(n)]
    return (f"{'/'.join(e['formats'])}, {e['bones']} bones, {e['lods']} LOD(s), {e['loop_s']:g} s loop"
            + (f", {', '.join(files).replace('_', ' ')}" if files else ""))


def _check_leaf_image(path: str | None) -> None:
    if path and not os.path.isfile(path):
        raise InputError(f"leaf image '{path}' does not exist; give an image file or drop "
                         "--leaf-image for the procedural leaf")


@dataclass
class Run:
    """How one job runs, beside what it is: overwrite (``force``), ``quiet``, its ``record`` (the
    report it leaves) and whether its folder has been ``begun``."""

    job: jobs.Job
    record: JobRecord
    force: bool = False
    quiet: bool = False
    begun: bool = False
    bark: object | None = None              # the bark from photos (BarkMaps), made once a job

    @property
    def out(self) -> str:
        return self.job.out

    def log(self, message: str) -> None:
        if not self.quiet:
            sys.stderr.write(message + "\n")


def _plan_generation(run: Run, req: gb.GenerateRequest):
    """Read what a generation needs before any work (:mod:`.core.generate.batch`): the species (mode
    without a video), the envelope, the audio, the leaf image."""
    plan = SimpleNamespace(req=req, model=None, species_label=None, envelope=None, envelope_label=None)
    if req.species is not None:
        plan.model, plan.species_label = gb.load_species_spec(req.species)
    spec_ = req.envelope or (gb.default_envelope(plan.model) if plan.model is not None else None)
    if spec_ is not None:
        plan.envelope, plan.envelope_label = gb.make_envelope(spec_, req.height_m)
    if req.audio is not None:
        gb.check_audio(req.audio)
    for c in req.cuts:                                     # a missing or foreign cut file: before any work
        load_cut(parse_cut_spec(c).path)
    _check_leaf_image(run.job.outputs.leaf_image)
    return plan


def _run_generation(run: Run, plan, outputs, look: tuple[float, str, str, float]) -> int:
    """Grow and write the trees of ``plan`` (its model and envelope set) into the job's folder, each
    tree's branch mesh with ``look`` (curliness, bark, forks, relief_cm)."""
    write = None
    if outputs is not None:
        def write(tree, folder):
            tree.meta["mesh"] = {"curliness": float(look[0]), "bark": look[1],     # the branch mesh's look
                                 "seed": int(tree.meta.get("seed", 0)), "forks": look[2],
                                 "relief_cm": float(look[3])}
            return _write_blender(run, outputs, tree, folder, run.log)
    t0 = time.monotonic()
    entries = gb.generate_trees(plan.model, plan.species_label, plan.envelope, plan.envelope_label, plan.req,
                                run.out, write, run.record.timed(_progress_printer(run.quiet)), run.log)
    bones = [e["bones"] for e in entries]
    run.record.add(trees=len(entries), leaf_clusters=sum(e["leaf_clusters"] for e in entries))
    if "bones" not in run.record.counts:                  # the Blender outputs count the rig they built
        run.record.add(bones=sum(bones))
    sys.stderr.write(f"done: {len(entries)} tree(s) of {plan.species_label} in {plan.envelope_label}, "
                     f"{min(bones)}-{max(bones)} bones, {entries[0]['frames']} frames, "
                     f"{time.monotonic() - t0:.1f} s -> {os.path.join(run.out, gb.INDEX)}\n")
    return 0


def _bark_files(job) -> list[str]:
    """The bark maps' files a job with bark photos writes in its folder."""
    from .core.detail.bark_photo import BARK_FILES
    return list(BARK_FILES) if job.outputs.bark_images else []


def _blender_step(job) -> object | None:
    """The Blender writers when the job asks for Blender outputs (checked against this Blender), else None."""
    if not job.outputs.blender:
        return None
    outputs = _blender_outputs()
    outputs.check_wanted(job.outputs.wanted)
    return outputs


def _generate_only(run: Run) -> int:
    """A :class:`~.core.jobs.GenerateJob`: ``--generate N --species S`` without a video."""
    job = run.job
    assert isinstance(job, jobs.GenerateJob)
    plan = _plan_generation(run, job.request)
    photos = _read_bark(run)
    _check_out(job.out, gb.planned_files(job.request, job.outputs.files) + _bark_files(job), run.force)
    outputs = _blender_step(job)
    own = read_bark_files(plan.model.bark_dir) if not photos and plan.model.bark_dir else None   # the species' bark
    _begin(run)
    _make_bark(run, photos)
    if own is not None:
        run.bark = own
        run.log(f"[bark] the species' bark from {plan.model.bark_dir}")
    return _run_generation(run, plan, outputs, (job.curliness, job.bark, job.forks, job.relief_cm))


def _variations(run: Run) -> int:
    """A :class:`~.core.jobs.VariationsJob`: the exemplars read (one line for an unfit one), then
    the variations written (:mod:`.core.generate.variations`)."""
    from .core.fileio import write_files
    from .core.generate import variations as gv
    from .core.generate.exemplars import read_exemplar
    job = run.job
    assert isinstance(job, jobs.VariationsJob)
    outlines = list(job.outlines) or ["-"] * len(job.exemplars)
    exemplars = [read_exemplar(path, job.params.size, None if ol == "-" else ol)
                 for path, ol in zip(job.exemplars, outlines)]
    _check_out(job.out, gv.planned_files(job.params.count), run.force)
    _begin(run)
    made = gv.make_variations(exemplars, job.params, run.record.timed(_progress_printer(run.quiet)))
    names = write_files(job.out, gv.variation_files(made, job.params, list(job.exemplars)))
    run.record.add(variations=len(made))
    sys.stderr.write(f"done: {len(made)} variation(s) of {len(exemplars)} exemplar(s) -> {job.out} "
                     f"({os.path.basename(names[0])} ... {gv.RECORD})\n")
    return 0


def _generate_from_tree(run: Run, plan, tree, name, outputs) -> int:
    """``VIDEO --generate N``: fit the species of the reconstructed ``tree``, save DIR/species.json,
    grow the trees (default envelope: the reconstruction's)."""
    plan.model = species.fit_species(tree, name)              # its branches: the twigs left out
    plan.species_label = os.path.join(run.out, gb.SPECIES_FILE)
    if run.bark is not None:                                   # its bark maps beside it: trees grown from it take them
        plan.model.bark_dir = "."
    species.save_species(plan.species_label, plan.model)
    run.log(f"[species] {plan.species_label}")
    if plan.envelope is None:
        plan.envelope, plan.envelope_label = envelope_from_meta(tree.meta), "reconstruction"
    s = run.job.settings
    return _run_generation(run, plan, outputs, (s.curliness, s.bark, s.forks, s.relief_cm))


def options(args) -> dict:
    """The batch options of a parsed command line by name (:data:`.core.jobs.OPTIONS`), None where
    the line left them out: what :func:`.core.jobs.from_flat` reads."""
    return {k: getattr(args, k) for k in jobs.OPTIONS}


def settings_from_args(args) -> pipeline.Settings:
    """The :class:`~.core.pipeline.Settings` of a reconstruction asked for by ``args``, checked
    (the job's, :func:`.core.jobs.settings_of`)."""
    return jobs.settings_of(jobs.check_types(options(args)))


#: the folder of tree k (1-based) when the outline holds several trees
TREE_FOLDER = "tree_{k}"


def _reconstruct(run: Run) -> int:
    """A :class:`~.core.jobs.ReconstructJob` or :class:`~.core.jobs.PhotoJob`: the reconstruction,
    its files and (with ``generate``) the trees. An outline of several trees (a .json of several
    polygons, a mask of several components) gives one folder ``DIR/tree_<k>/`` per tree, from one
    decode and one tracking pass."""
    job = run.job
    assert isinstance(job, jobs.ReconstructJob)
    plan = _plan_generation(run, job.generate) if job.generate is not None else None
    files = job.outputs.files
    names = ["skeleton.npz", "tree3d.npz", "overlay.png"] + (["overlay.mp4"] if job.outputs.overlay_video else []) \
        + (["result.npz"] if job.outputs.npz else []) \
        + (files if plan is None else gb.planned_files(plan.req, files, with_species=True))
    _check_leaf_image(job.outputs.leaf_image)
    settings = job.settings
    photo = None
    if isinstance(job, jobs.PhotoJob):  # one frame: the tree sways as its species (core/generate/photo.py)
        check_photo(job.video)
        photo = job.motion
        if photo.species:
            gb.load_species_spec(photo.species)        # a missing or broken species file fails now
    n_trees = pipeline.count_outlines(job.video, job.outline, settings.scale, settings.frames)
    if n_trees > 1 and plan is not None:
        raise InputError(f"--generate grows trees of one reconstructed tree, and the outline holds {n_trees}; "
                         "give one outline")
    folders = [job.out] if n_trees == 1 else [os.path.join(job.out, TREE_FOLDER.format(k=k + 1))
                                              for k in range(n_trees)]
    photos = _read_bark(run)
    for folder in folders:
        _check_out(folder, names + _bark_files(job), run.force)
    outputs = _blender_step(job)
    _begin(run)
    from_video = VIDEO_BARK in job.outputs.bark_images
    if not from_video:
        _make_bark(run, photos)
    cb = run.record.timed(_progress_printer(run.quiet))
    results = pipeline.run_all(job.video, job.outline, settings, cb)
    info = results[0].info
    run.record.video = {"width": info.width, "height": info.height, "fps": float(info.fps),
                        "frames": [int(results[0].start), int(results[0].stop)],
                        "time_base": "index / fps" if results[0].tracks.times is None else "frame timestamps"}
    base = os.path.splitext(os.path.basename(job.video))[0] or "Tree"
    tree_names = [f"Tree {base}"] if n_trees == 1 else [f"Tree {base} {k + 1}" for k in range(n_trees)]
    trees = pipeline.build_shot(results, settings, tree_names, cb, photo=photo)     # one scale, each where it stands
    if from_video:                                   # the first tree's trunk in frame 1 as a bark photo
        strip, why = _video_bark(results[0], trees[0])
        if strip is None:
            w = f"--bark-image video: {why}; the bark is made from the other photos or stays procedural"
            sys.stderr.write(f"warning: {w}\n")
            run.record.warn(w)
        else:
            run.log(f"[bark] {why}")
            photos.append(strip)
        _make_bark(run, photos, len(photos) - (strip is not None))
    for res, tree, folder in zip(results, trees, folders):
        _write_tree(run, res, tree, folder, outputs if plan is None else None, cb)
    if plan is not None:
        return _generate_from_tree(run, plan, trees[0], base, outputs)
    return 0


def _write_blender(run: Run, outputs, tree, out: str, report=None) -> dict:
    """The Blender outputs of ``tree`` in ``out`` with the job's look, loop and game options; the
    built rig's counts go to the job's record (every batch path writes them through here)."""
    o = run.job.outputs
    return outputs.write_outputs(tree, out, o.wanted, overwrite=run.force, leaf_image=o.leaf_image,
                                 report=report or (lambda m: sys.stderr.write(m + "\n")), loop_s=o.game.loop_s,
                                 game=o.game, stats=run.record.counts, bark_maps=run.bark, billboard_px=o.billboard)


def _read_bark(run: Run) -> list:
    """The job's bark photos read (one line for a missing or unfit one) before any work; [] without."""
    photos = []
    for path in run.job.outputs.bark_images:
        if path == VIDEO_BARK:                    # the trunk's own pixels, once frame 1 is traced
            continue
        photos.extend(read_bark_photo(f) for f in bark_photo_files(path))
    return photos


def _video_bark(res, tree):
    """``(strip or None, why)``: frame 1's trunk of ``res`` straightened (:mod:`.core.detail.trunk_strip`)."""
    from .core.detail.trunk_strip import trunk_strip
    from .core.reconstruct.branch_fit import tree_map
    frame = pipeline.first_frame(res)
    if frame is None:
        return None, "frame 1 could not be read again"
    sk = res.skeleton
    n = len(sk.parents)
    radius_px = tree.radius[:n].astype(float) / float(tree.meta.get("metres_per_px", 1.0))
    tmap = tree_map(frame, res.outline.mask)
    return trunk_strip(frame, sk.parents, sk.nodes2d[0], radius_px, tmap.tree if tmap is not None else None)


def _make_bark(run: Run, photos: list, files: int | None = None) -> None:
    """The bark tile of the job's photos, its files in the job's folder (DIR/bark_*.png, bark.json);
    ``files`` how many of them are photo files (the rest: the video's trunk; None: all)."""
    if not photos:
        return
    o = run.job.outputs
    run.bark = bark_maps(photos, o.bark, run.record.timed(_progress_printer(run.quiet)))
    write_bark_files(run.bark, run.out, list(o.bark_images))
    run.record.add(bark_tile_px=run.bark.textures.albedo.shape[0])
    run.log(f"[bark] a {run.bark.scale_cm:g} cm tile from {len(photos)} photo(s): moss "
            f"{run.bark.moss[0]:.1%} -> {run.bark.moss[1]:.1%}, lichen {run.bark.lichen[0]:.1%} -> {run.bark.lichen[1]:.1%}")
    for k, said in enumerate(run.bark.height_from):
        run.log(f"[bark] photo {k + 1}'s height: {said}")
    files = len(photos) if files is None else files
    if files > 1 and not any(s.startswith("stereo") for s in run.bark.height_from):
        w = (f"the {files} bark photos do not overlap (no two share {MIN_INLIERS} matches): their relief "
             "is from their shading; photos of the same bark a step apart give it by parallax")
        sys.stderr.write(f"warning: {w}\n")
        run.record.warn(w)


def _write_tree(run: Run, res, tree, out: str, outputs, cb) -> None:
    """Write one reconstructed tree's files (its 2D result ``res``, its 3D ``tree``) into ``out``,
    and its Blender outputs with ``outputs`` (None: none, or they are the generated trees')."""
    job = run.job
    assert isinstance(job, jobs.ReconstructJob)
    os.makedirs(out, exist_ok=True)
    for w in pipeline.tree_warnings(res, tree):
        sys.stderr.write(f"warning: {w}\n")
        run.record.warn(w)
    run.record.add(trees=1, tracks=res.tracks.n_tracks, nodes=tree.n_nodes,
                   leaf_clusters=tree.leaves.count if tree.leaves is not None else 0)
    meta = {"video": os.path.abspath(job.video), "frames": [res.start, res.stop],
            "levels": job.settings.levels, "scale": job.settings.scale, "version": __version__}
    skeleton_io.save_skeleton(os.path.join(out, "skeleton.npz"), res.skeleton, meta)
    tree.meta.update(meta)
    save_tree(os.path.join(out, "tree3d.npz"), tree)
    if job.outputs.npz:
        arrays = skeleton_io.skeleton_arrays(res.skeleton, meta)
        arrays["nodes3d"] = tree.nodes3d[:, :res.skeleton.n_nodes]     # twigs are appended after
        atomic_savez(os.path.join(out, "result.npz"), **arrays)
    overlay.write_overlays(res.info, res.start, res.skeleton, res.tracks,
                           os.path.join(out, "overlay.png"),
                           os.path.join(out, "overlay.mp4") if job.outputs.overlay_video else None, cb,
                           res.foreground.mask if res.foreground is not None else None)
    if outputs is not None:
        cb("blender outputs", 0.0)
        _write_blender(run, outputs, tree, out)
    conf = res.skeleton.confidence
    sure = "" if conf is None else f", {node_motion.confidence_summary(conf)}"
    sys.stderr.write(f"done: {res.skeleton.n_nodes} nodes, {res.tracks.n_tracks} tracks, "
                     f"{res.tracks.n_frames} frames{sure} -> {out}\n")


#: the farm command's own options (never a job's)
FARM_OPTIONS = ("farm", "scheduler", "workers", "job_timeout", "blender")
#: errors of the disk a job writes to: the user's to fix (exit 2), not ours
USERS_DISK = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG)
#: the options --job allows beside it on the line
BESIDE_JOB = ("job", "force", "quiet", "dry_run")


def job_argv(doc, path: str) -> list[str]:
    """The command line of a job file's JSON object (its keys are the batch options' names, ``-`` or
    ``_``; a switch takes true/false, a number a number, the rest a string); :class:`InputError`
    for anything else (:func:`.core.jobs.to_argv`)."""
    return jobs.to_argv(doc, path)


def _job_file(args) -> dict:
    """The options of ``args.job`` (the line may add only --force, --dry-run, --quiet)."""
    bare = vars(build_parser().parse_args(["--job", args.job]))
    extra = [k for k, v in bare.items() if k not in BESIDE_JOB and getattr(args, k) != v]
    if extra:
        raise InputError(f"--{extra[0].replace('_', '-')} given beside --job; put it in {args.job} instead")
    if not os.path.isfile(args.job):
        raise InputError(f"job file '{args.job}' does not exist; give the path of a JSON job file")
    doc = read_json(args.job, f"job file '{args.job}'", "write the job as one JSON object of batch options")
    return jobs.check_types(doc, args.job)


def record(job: jobs.Job | dict, argv: list[str]) -> JobRecord:
    """The job's record: its settings (:func:`.core.jobs.settings_doc`; a job refused before it was
    one: the options given) and input identity (with the content of the files its settings name,
    :func:`.core.jobs.side_files`)."""
    if isinstance(job, dict):
        settings = {k: v for k, v in sorted(job.items()) if k not in jobs.PLACES and v is not None}
        video, outline = job.get("video") or job.get("tree"), job.get("outline")
    else:
        settings = jobs.settings_doc(job)
        video = job.tree if isinstance(job, jobs.ExportJob) else getattr(job, "video", None)
        outline = getattr(job, "outline", None)
    ident = (identity.files_identity(list(job.exemplars) + [o for o in job.outlines if o != "-"], "exemplars")
             if isinstance(job, jobs.VariationsJob)
             else identity.input_identity(video, outline))
    side = identity.files_identity(jobs.side_files(settings), "side_files")
    if ident is not None and side is not None:          # cuts, bark photos, species...: their content too
        ident = dict(ident, side_files=side["side_files"], side_sha256=side["sha256"])
    return JobRecord(list(argv), settings, identity.settings_hash(settings), __version__, input=ident)


class Tee:
    """stderr that also keeps its lines for job.log."""

    def __init__(self, stream, lines: list[str]):
        self._stream, self._lines = stream, lines

    def write(self, text: str) -> int:
        self._lines.append(text)
        return self._stream.write(text)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _exports_only(run: Run) -> int:
    """An :class:`~.core.jobs.ExportJob` (``--tree DIR/tree3d.npz --out DIR2 --gltf ...``): the
    Blender outputs of a saved tree."""
    job = run.job
    assert isinstance(job, jobs.ExportJob)
    if not os.path.isfile(job.tree):
        raise InputError(f"tree file '{job.tree}' does not exist; give a tree3d.npz an earlier job wrote")
    _check_leaf_image(job.outputs.leaf_image)
    photos = _read_bark(run)
    _check_out(job.out, job.outputs.files + job.outputs.game.files() + _bark_files(job), run.force)
    outputs = _blender_step(job)
    tree = load_tree(job.tree)                     # exists: checked above
    _begin(run)
    _make_bark(run, photos)
    run.record.add(trees=1, nodes=tree.n_nodes, leaf_clusters=tree.leaves.count if tree.leaves is not None else 0)
    run.record.timed(None)("blender outputs", 0.0)
    _write_blender(run, outputs, tree, job.out)
    sys.stderr.write(f"done: the outputs of {job.tree} -> {job.out}\n")
    return 0


def _begin(run: Run) -> None:
    """The work starts: the folder gets a ``running`` report (a killed run leaves it saying so)."""
    os.makedirs(run.out, exist_ok=True)
    run.record.write(run.out)
    run.begun = True


def run_job(run: Run) -> int:
    """Run the job of ``run`` (its record set) by its kind; the one runner of the batch, a job
    file, the farm's tasks and :func:`.api.run_job`."""
    job = run.job
    if isinstance(job, jobs.VariationsJob):
        return _variations(run)
    if isinstance(job, jobs.ExportJob):
        return _exports_only(run)
    if isinstance(job, jobs.GenerateJob):
        return _generate_only(run)
    return _reconstruct(run)


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
    sys.stderr = Tee(stderr, lines)
    run: Run | None = None
    flat: dict = {}
    prior, status, message = None, "ok", None
    try:
        try:
            if args.farm:
                from . import cli_farm
                return cli_farm.main(args, argv, SimpleNamespace(build_parser=build_parser, options=options,
                                                                 record=record))
            flat = _job_file(args) if args.job else options(args)
            if not flat.get("out"):
                parser.error("the following arguments are required: --out")
            prior = read_report(flat["out"]) if os.path.isdir(flat["out"]) else None
            job = jobs.from_flat(flat, args.job or "the job")
            run = Run(job, record(job, argv), force=args.force, quiet=args.quiet)
            run.record.log = lines
            decision = identity.decide(prior, run.record.settings_sha256, run.record.input, args.force)
            if args.dry_run:
                print(f"{decision.action}: {job.out}: {decision.why}")
                return 0
            if decision.action == "skip":
                sys.stderr.write(f"skipped: {job.out}: {decision.why}\n")
                return 0
            if decision.action == "redo":
                run.force = True                  # the files there are our unfinished run's
            return run_job(run)
        except InputError as exc:
            status, message = "bad_input", str(exc)
            sys.stderr.write(f"error: {exc}\n")
            return 2
        except OSError as exc:
            if exc.errno not in USERS_DISK:
                raise
            where = exc.filename or flat.get("out")
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
        if not args.farm and not args.dry_run and flat.get("out"):
            if run is None:                        # refused before it was a job: its options are its record
                run = Run(jobs.ExportJob("", flat["out"], jobs.JobOutputs()), record(flat, argv))
                run.record.log = lines
            _final_report(run, prior, status, message)


def _final_report(run: Run, prior: dict | None, status: str, message: str | None) -> None:
    """Write the job's report unless it never reached its folder: a failure before the work
    started reports only into an existing folder that holds no finished job's report."""
    out = run.out
    if not run.begun and not (os.path.isdir(out) and (prior is None or prior.get("status") != "ok")):
        return
    if not run.begun and status == "ok":
        return                                    # skipped: the done job's report stays
    try:
        run.record.finish(status, message, out)
        run.record.write(out)
    except OSError as exc:                         # a full disk or a read-only folder: say it, keep the code
        if status == "ok" or exc.errno not in USERS_DISK:     # a full disk was the one line already
            sys.stderr.write(f"warning: report.json not written in {out} ({exc.strerror})\n")
