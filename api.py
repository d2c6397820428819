"""The scripting API for pipeline TDs: stable from version 0.1 on (names, arguments, results).

    from tree_from_video import api                      # in Blender: bl_ext.user_default.tree_from_video
    result = api.reconstruct("oak.mp4", "oak_outline.json", frames="0:240", levels=6)
    tree = api.build_3d(result, twigs=2, bark="rough", height_m=12)
    api.save_tree(tree, "oak/tree3d.npz");  tree = api.load_tree("oak/tree3d.npz")
    print(tree.meta["metres_per_px"], tree.meta["base_px"], tree.meta["video_size"])
    trees = api.generate("broad", 3, envelope="heart", seed=7)          # new trees of a species
    api.save_cut(tree, ["B040"], "limb.npz")                            # a tree-cut: that branch
    trees = api.generate("broad", 2, cuts=["limb.npz", "limb.npz@0.5,0,6"])   # trees that contain it
    game = api.loop(tree, 8.0)                                          # a seamless 8 s loop
    job = api.job(video="oak.mp4", outline="oak.json", out="oak", gltf=True, bones=64)   # a batch job
    report = api.run_job(job)                  # run as batch.py runs it: oak/report.json, the files
    # inside Blender (bpy):
    built = api.build_tree(bpy.context, tree, "Oak")                    # armature, branches, leaves
    api.export(built, "//oak.glb")                                      # format from the extension

Settings are keywords, with the defaults and ranges of the panel and the batch options (see
:func:`settings`); a bad value raises :class:`InputError` with one sentence naming the fix.
``tree`` is a :class:`Tree3D`: ``parents (N,)``, ``nodes3d (F, N, 3)`` metres (x right, y away
from the camera, z up), ``radius (N,)`` metres, ``fps``, ``leaves`` and ``meta``
(:mod:`.core.meta` lists its keys).
"""
from __future__ import annotations

import dataclasses
import os
import sys
from typing import Any

from .core import formats, jobs, pipeline
from .core.errors import Cancelled, InputError
from .core.progress import ProgressFn
from .core.reconstruct.run import Result
from .core.tree3d import Tree3D
from .core.tree3d import load_tree as _load_tree
from .core.tree3d import save_tree as _save_tree

__all__ = ["Cancelled", "InputError", "Result", "Tree3D", "build_3d", "build_tree", "export", "generate", "job",
           "load_tree", "reconstruct", "run_job", "save_cut", "save_tree", "settings", "species_library"]

#: Keywords of :func:`settings` beyond the fields of :class:`pipeline.Settings` (levels, skeleton,
#: frames, scale, height_m, curliness, bark, fit_branches, cache_dir, ...).
SHORTCUTS = {
    "twigs": "twig depth, 0..6 (0: none)",
    "conifer": "the same as form=\"conifer\" (bool)",
    "solver": "3D motion solver: probabilistic or deterministic",
    "leaves": "leaf clusters (bool; False: bare branches)",
    "leaf_density": "share of the leaf seeds kept, (0, 1]",
    "leaf_cards": "leaf cards per cluster",
    "flutter_hz": "leaf flutter frequency, Hz",
    "leaf_colour": "leaf colour: albedo, video or #RRGGBB",
}


def settings(**kw: Any) -> pipeline.Settings:
    """:class:`pipeline.Settings` from keywords: any field of ``Settings`` (``levels=6``,
    ``frames="0:240"``, ``height_m=10``, ``curliness=0.3``, ``bark="rough"``, ...) or one of
    :data:`SHORTCUTS` (``twigs=2``, ``conifer=True``, ``leaves=False``, ``leaf_density=0.5``, ...).
    Unset keywords keep the product's defaults (those of the panel and the CLI)."""
    s = pipeline.from_flat(kw)
    pipeline.check_settings(s)
    return s


def reconstruct(video: str | os.PathLike, outline, progress: ProgressFn | None = None, **kw: Any) -> Result:
    """The 2D reconstruction of ``video``: tracks, motion hierarchy and moving 2D skeleton
    (``result.skeleton.nodes2d (F, N, 2)`` px of frame 1). ``outline``: a polygon ``.json`` or mask
    image path, ``"auto"``, or an ``(M, 2)`` array of frame-1 pixels. ``progress(stage, fraction)``
    may raise :class:`Cancelled` to stop. Keywords: :func:`settings`."""
    return pipeline.run(os.fspath(video), outline, settings(**kw), progress)


def build_3d(result: Result, progress: ProgressFn | None = None, name: str = "Tree", **kw: Any) -> Tree3D:
    """The animated 3D tree of a :func:`reconstruct` result: lifted, its motion solved, branch
    widths from frame 1, twigs and leaves as asked (keywords: :func:`settings`)."""
    return pipeline.build_3d(result, settings(**kw), name=name, progress=progress)


def save_tree(tree: Tree3D, path: str | os.PathLike) -> str:
    """Write ``tree`` to ``path`` (``.npz``, atomically; what Blender builds from). Returns the
    absolute path."""
    _save_tree(path, tree)
    return os.path.abspath(path)


def load_tree(path: str | os.PathLike) -> Tree3D:
    """A tree saved by :func:`save_tree` or by the batch job (``DIR/tree3d.npz``)."""
    if not os.path.isfile(path):
        raise InputError(f"tree file '{path}' does not exist; give a tree3d.npz written by the add-on")
    return _load_tree(path)


def generate(species: str | os.PathLike = "broad", n: int = 1, envelope: str | None = None,
             seed: int = 0, height_m: float | None = None, progress: ProgressFn | None = None,
             **kw: Any) -> list[Tree3D]:
    """``n`` new animated trees of a species (a library name: broad, sparse, conifer, or a species
    ``.json``), grown in ``envelope`` (circle, triangle, pentagon, heart, a silhouette image; None:
    the species' default), tree ``i`` with seed ``seed + i``. Keywords: those of
    :class:`~.core.generate.growth.GrowParams` (``node_budget``, ``n_frames``, ``wind``,
    ``leaf_density``, ``cuts``: tree-cut files, ``"FILE"`` where it fits or ``"FILE@X,Y,Z"``, ...)."""
    from .core.generate import batch as gb
    from .core.generate.growth import GrowParams, grow_tree
    from .core.progress import report, sub_progress
    if not 1 <= int(n) <= gb.MAX_TREES:
        raise InputError(f"{n} trees: give a number from 1 to {gb.MAX_TREES}")
    model, _ = gb.load_species_spec(os.fspath(species))
    height_m = gb.GenerateRequest().height_m if height_m is None else height_m   # the one default (10 m)
    env, _ = gb.make_envelope(envelope or gb.default_envelope(model), height_m)
    known = {f.name for f in dataclasses.fields(GrowParams)}
    bad = sorted(set(kw) - known)
    if bad:
        raise InputError(f"unknown generation setting '{bad[0]}'; use one of {', '.join(sorted(known))}")
    if "cuts" in kw:                               # "FILE" or "FILE@X,Y,Z", as the batch's --cut
        from .core.generate.cuts import parse_cut_spec
        kw["cuts"] = tuple(c if not isinstance(c, str) else parse_cut_spec(c) for c in kw["cuts"])
    trees = []
    for i in range(int(n)):
        p = GrowParams(**{**kw, "seed": int(seed) + i})
        trees.append(grow_tree(model, env, p, progress=sub_progress(progress, i / n, (i + 1) / n)))
    report(progress, "generating", 1.0)
    return trees


def job(**options: Any) -> jobs.Job:
    """The batch job the options describe, by the batch options' names (``video``, ``outline``,
    ``out``, ``levels``, ``gltf``, ``bones``, ``generate``, ``species``…; :data:`core.jobs.OPTIONS`):
    a :class:`~.core.jobs.ReconstructJob`, ``PhotoJob``, ``GenerateJob`` or ``ExportJob``, typed and
    checked as the command line's (:func:`core.jobs.from_flat`). ``jobs.to_flat(job)`` gives the
    options back, as a job file (``batch.py --job FILE``) or a farm's list holds them."""
    return jobs.from_flat(options, "api.job()")


def run_job(job: "jobs.Job | dict", force: bool = False, quiet: bool = True) -> dict:
    """Run ``job`` (a :func:`job`, or its options) as ``batch.py`` runs it, in this process: its
    folder gets the files, ``report.json`` and ``job.log``; a done job (its report ``ok``, the same
    settings and input) is skipped unless ``force``. Returns the report (status ``ok``, ``error``
    or ``cancelled``; a skipped job's is the one it left); bad input raises :class:`InputError` with
    the report's one line. The Blender outputs need bpy (this Blender, or the bpy wheel)."""
    from . import cli
    from .core.farm.report import read_report
    flat = jobs.check_types(job, "api.run_job()") if isinstance(job, dict) else jobs.to_flat(job)
    if not flat.get("out"):
        raise InputError("the job has no out folder; give out=FOLDER")
    jobs.from_flat(flat, "api.run_job()")            # its options' errors raised here, before any folder
    said: list[str] = []
    stderr = sys.stderr
    sys.stderr = cli.Tee(stderr, said)              # the runner's one line, should it refuse the job
    try:
        code = cli.main(jobs.to_argv(flat) + (["--force"] if force else []) + (["--quiet"] if quiet else []))
    finally:
        sys.stderr = stderr
    report = read_report(flat["out"]) or {}
    if code == 2:
        errors = [ln[len("error: "):] for ln in "".join(said).splitlines() if ln.startswith("error: ")]
        raise InputError(report.get("message") or (errors[-1] if errors else f"the job in {flat['out']} was refused"))
    return report


def loop(tree: Tree3D, seconds: float) -> Tree3D:
    """``tree`` cut to a seamless loop of about ``seconds`` (a length past the clip's takes the whole
    clip with its seam blended; :func:`core.loop.loop_tree`): ``L + 1`` frames, the last
    equal to the first, the leaves' flutter and flap on whole periods; built in Blender its action
    is named ``<tree>_loop`` and every export names its animation so."""
    from .core.loop import loop_tree
    return loop_tree(tree, seconds)[0]


def save_cut(tree: Tree3D, bones, path: str | os.PathLike, whole_branch: bool = True,
             overwrite: bool = False) -> str:
    """Keep the branch of ``tree`` made of ``bones`` (names ``"B040"`` or node indices; with
    ``whole_branch`` every bone beyond them too) and its branch mesh as a tree-cut file ``path``
    (``.npz``, what the panel's Save Cut writes; :mod:`.core.tree_cut`). Returns the absolute path."""
    from .core.asset.cut_mesh import with_mesh
    from .core.tree_cut import cut_from_tree
    from .core.tree_cut import save_cut as _save_cut
    _save_cut(path, with_mesh(tree, cut_from_tree(tree, bones, whole_branch)), overwrite=overwrite)
    return os.path.abspath(path)


def species_library() -> dict[str, str]:
    """The shipped species: ``{name: path of its .json}`` (for :func:`generate`)."""
    from .core.generate.species import species_library as _library
    return _library()


# ----------------------------------------------------------------------------- in Blender

def build_tree(context, tree: Tree3D, name: str, **kw: Any) -> dict:
    """Build ``tree`` in the scene of ``context`` as the collection ``name`` (armature keyed every
    frame, skinned branch mesh, leaf bones and mesh): ``{"collection", "armature", "mesh",
    "leaves", "action"}``. Keywords: ``replace``, ``mesh``, ``leaves``, ``leaf_image``,
    ``curliness``, ``bark`` (see :func:`operators.scene.build.build_tree`). Needs bpy."""
    from .operators.scene.build import build_tree as _build
    return _build(context, tree, name, **kw)


def export(tree_or_objects, path: str | os.PathLike, overwrite: bool = False) -> str:
    """Export to ``path``, the format from its extension (``.fbx``, ``.glb``, ``.usd``/``.usdc``/
    ``.usda``): a :func:`build_tree` result, a collection, objects, or a
    :class:`Tree3D` (built in a temporary collection that is removed again). Existing files are
    kept unless ``overwrite``. Returns the absolute path written. Needs bpy."""
    import bpy

    from .operators.scene import export as ex
    from .operators.scene.objects import remove_collection
    path = bpy.path.abspath(os.fspath(path))
    fmt = formats.for_path(path)
    if fmt is None:
        raise InputError(f"'{path}': unknown export format; end the name in {', '.join(formats.interchange_extensions())}")
    temp = None
    if isinstance(tree_or_objects, Tree3D):
        temp = build_tree(bpy.context, tree_or_objects, f"{tree_or_objects.name} export")
        tree_or_objects = temp
    try:
        if isinstance(tree_or_objects, dict):
            objects = list(tree_or_objects["collection"].all_objects)
        elif isinstance(tree_or_objects, bpy.types.Collection):
            objects = list(tree_or_objects.all_objects)
        else:
            objects = list(tree_or_objects)
        assert fmt.writer is not None
        getattr(ex, fmt.writer)(path, objects, overwrite=overwrite)
    finally:
        if temp is not None:
            remove_collection(temp["collection"])
    return os.path.abspath(path)

