"""A run as a typed, serializable job: what it reads, its settings and what it writes (issue 34).

Five kinds, each a dataclass:

* :class:`ReconstructJob` — a video and its outline → the moving skeleton, the 3D tree and the
  files asked for (with ``generate`` also new trees of the species fitted from it);
* :class:`PhotoJob` — a photo and its outline → a tree that sways as its species
  (:mod:`.generate.photo`);
* :class:`GenerateJob` — new trees of a species, without a video;
* :class:`VariationsJob` — new RGBA tree images from RGBA exemplars (:mod:`.generate.variations`);
* :class:`ExportJob` — the Blender outputs of a tree an earlier job saved (the exports step
  alone: a farm runs the others on any worker and this one on Blender workers).

Every caller builds them with :func:`from_flat` from the batch options by name (:data:`OPTIONS`:
``video``, ``outline``, ``out``, ``levels``, ``gltf``, ``bones``…; the command line, a ``--job``
file, a farm's list, :func:`api.job`): one place where options are typed, checked and filled with
the product's defaults (the engine preset, the reconstruction's :class:`~.pipeline.Settings`
through :func:`~.pipeline.from_flat`, the generation request, the photo's motion).
:func:`to_flat` gives the options back (a job file, the report's settings, a farm's command line
through :func:`to_argv`): ``from_flat(to_flat(job)) == job``. Checks that read files (a video, a
species, an image) are the runner's, when the job starts.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Union

from .asset.billboard import BILLBOARD_PX
from .asset.billboard import FILES as BILLBOARD_FILES
from .asset.game import GameSettings, preset
from .detail.bark_photo import BarkPhotoParams
from .detail.trunk_strip import VIDEO_BARK
from .errors import InputError
from .formats import FORMATS
from .generate.batch import GenerateRequest, check_request
from .generate.photo import PhotoMotion, is_photo
from .generate.variations import VariationParams
from .loop import LoopSettings
from .params import check, spec
from .pipeline import Settings, check_settings
from .pipeline import from_flat as settings_from_flat

#: the batch options a job is made of, by name, and the JSON type each takes (bool: a switch);
#: None or a missing name is the product's default
OPTIONS: dict[str, type] = {
    "video": str, "outline": str, "out": str, "tree": str, "npz": bool,
    "levels": int, "frames": str, "skeleton": str, "scale": float, "form": str, "conifer": bool,
    "limbs": str, "limb_species": str, "depth": str, "solver": str, "height": float, "twigs": int,
    "no_branch_fit": bool, "curliness": float, "bark": str, "forks": str, "bark_relief": float,
    "no_leaves": bool, "leaf_density": float,
    "leaf_cards": int, "flutter_hz": float, "leaf_colour": str, "leaf_image": str,
    "engine": str, "loop": float, "bones": int, "lods": int, "pivot_painter": bool, "collision": bool,
    "impostor": bool, "bone_texture": bool, "viewer": bool,
    **{f.flag: bool for f in FORMATS}, "no_video": bool,
    "generate": int, "species": str, "envelope": str, "wind": float, "audio": str, "seed": int,
    "nodes": int, "frames_out": int, "seconds": float,
    "bark_image": list, "moss": float, "lichen": float, "bark_scale": float,
    "fold_alpha": float, "candidates": int, "sigma_track": float, "sigma_shape": float, "max_step": float,
    "max_total": float, "flutter_gain": float, "max_leaf_clusters": int,
    "variations": int, "exemplars": list, "billboard": int, "envelope_variation": float,
    "allometry": bool, "exemplar_outlines": list, "cut": list,
}
#: the options that say where a job reads and writes (not its settings: not in its settings hash)
PLACES = ("video", "outline", "out", "tree")
#: the options that name files a job reads besides its video and outline: their content is part of
#: the job's input identity (:func:`side_files`), so a farm re-runs a job whose cut or photo changed
SIDE_FILES = ("bark_image", "cut", "leaf_image", "species", "envelope", "audio")
#: the game options an ``engine`` preset fills when not given
GAME = ("bones", "lods", "loop", "pivot_painter", "bone_texture", "collision", "viewer", "impostor")
#: the reconstruction's options → the :func:`~.pipeline.from_flat` names they set
SETTINGS = {"levels": "levels", "frames": "frames", "skeleton": "skeleton", "scale": "scale", "form": "form",
            "limbs": "limbs", "limb_species": "limb_species", "depth": "depth", "solver": "solver",
            "height": "height_m", "twigs": "twigs", "curliness": "curliness", "bark": "bark",
            "forks": "forks", "bark_relief": "relief_cm",
            "leaf_density": "leaf_density", "leaf_cards": "leaf_cards", "flutter_hz": "flutter_hz",
            "leaf_colour": "leaf_colour", "fold_alpha": "fold_alpha", "candidates": "candidates",
            "sigma_track": "sigma_track", "sigma_shape": "sigma_shape", "max_step": "max_step",
            "max_total": "max_total", "flutter_gain": "flutter_gain", "max_leaf_clusters": "max_leaf_clusters"}
#: options of a generation only (a photo's sway takes ``species`` and ``seconds`` too)
GENERATION_ONLY = ("species", "envelope", "audio", "frames_out", "seconds", "envelope_variation", "allometry", "cut")
FORMAT_FLAGS = ", ".join("--" + f.flag for f in FORMATS)


def json_type(value: Any) -> str:
    """How a job file's value reads to its author ("a string", "a number", "true/false"…)."""
    return {bool: "true/false", int: "a number", float: "a number", str: "a string", list: "a list",
            dict: "an object"}.get(type(value), type(value).__name__)


@dataclass
class JobOutputs:
    """What a job writes besides its core files: ``formats`` the Blender outputs by their registry
    flag (:data:`core.formats.FORMATS`: "fbx", "gltf"…), ``game`` the game settings they are built
    with (the engine preset applied; its ``loop_s`` the loop they carry), ``leaf_image`` (None: the
    procedural leaf), ``npz`` the arrays of ``result.npz``, ``overlay_video`` ``overlay.mp4``;
    ``bark_images`` photos of bark the bark is made from (none: procedural) with ``bark`` their
    :class:`~.detail.bark_photo.BarkPhotoParams` (moss, lichen, the tile's scale); ``billboard`` the
    billboard's pixels on its longer side (0: none; :mod:`.asset.billboard`, rendered in Blender)."""

    formats: tuple[str, ...] = ()
    game: GameSettings = field(default_factory=GameSettings)
    leaf_image: str | None = None
    npz: bool = False
    overlay_video: bool = True
    bark_images: tuple[str, ...] = ()
    bark: BarkPhotoParams = field(default_factory=BarkPhotoParams)
    billboard: int = 0

    @property
    def blender(self) -> bool:
        """Whether the job needs Blender (an export, or a render like the billboard)."""
        return bool(self.formats) or self.billboard > 0

    @property
    def wanted(self) -> dict[str, bool]:
        """``{flag: asked for}`` for every registered format."""
        return {f.flag: f.flag in self.formats for f in FORMATS}

    @property
    def files(self) -> list[str]:
        """The Blender outputs' file names, in the registry's order, and the billboard's."""
        return [f.file for f in FORMATS if f.flag in self.formats] + (list(BILLBOARD_FILES) if self.billboard else [])


@dataclass
class ReconstructJob:
    """A video (``video``, ``outline``: a polygon .json, a mask image or "auto") reconstructed into
    ``out``; ``generate`` new trees of the species fitted from it (None: none)."""

    kind: ClassVar[str] = "reconstruct"
    video: str
    outline: str
    out: str
    settings: Settings
    outputs: JobOutputs
    generate: GenerateRequest | None = None


@dataclass
class PhotoJob(ReconstructJob):
    """A photo traced like a video's first frame; its tree sways as ``motion`` says."""

    kind: ClassVar[str] = "photo"
    motion: PhotoMotion = field(default_factory=PhotoMotion)


@dataclass
class GenerateJob:
    """``request.count`` new trees of a species written to ``out`` (``out/tree_000/``…), with the
    branch mesh's ``curliness``, ``bark``, ``forks`` and ``relief_cm``."""

    kind: ClassVar[str] = "generate"
    request: GenerateRequest
    out: str
    outputs: JobOutputs
    curliness: float = Settings().curliness
    bark: str = Settings().bark
    forks: str = Settings().forks
    relief_cm: float = Settings().relief_cm


@dataclass
class ExportJob:
    """The Blender outputs of the saved tree ``tree`` (a ``tree3d.npz``) written to ``out``, with the
    branch mesh's look its file records."""

    kind: ClassVar[str] = "export"
    tree: str
    out: str
    outputs: JobOutputs


@dataclass
class VariationsJob:
    """``params.count`` new RGBA tree images made from the RGBA pictures ``exemplars``, written to
    ``out`` (``variation_000.png``…, ``variations.json``); an exemplar may be a photo cut out by its
    entry in ``outlines``."""

    kind: ClassVar[str] = "variations"
    exemplars: tuple[str, ...]
    out: str
    params: VariationParams
    outputs: JobOutputs = field(default_factory=JobOutputs)
    outlines: tuple[str, ...] = ()     # per exemplar: a photo's outline, or "-" (an RGBA image); () all RGBA


Job = Union[ReconstructJob, PhotoJob, GenerateJob, ExportJob, VariationsJob]


def variations_of(o: dict) -> VariationsJob:
    """The :class:`VariationsJob` of the options ``o`` (``variations`` given): exemplars needed, and
    nothing of a tree's run beside them."""
    exemplars = tuple(o.get("exemplars") or ())
    if not exemplars:
        raise InputError("--variations N makes new trees from pictures of trees; add --exemplars A.png B.png "
                         "(RGBA, transparent around the tree)")
    for opt in ("video", "tree", "generate", "outline"):
        if o.get(opt) is not None:
            name = "VIDEO" if opt == "video" else "--" + opt
            raise InputError(f"--variations makes tree images from --exemplars; drop {name} (run it as a job of its own)")
    outlines = tuple(o.get("exemplar_outlines") or ())
    if outlines and len(outlines) != len(exemplars):
        raise InputError(f"--exemplar-outlines gives {len(outlines)} outline(s) for {len(exemplars)} exemplar(s); give "
                         "one per exemplar, '-' for an RGBA one")
    p = VariationParams(count=o["variations"], seed=o.get("seed", VariationParams().seed))
    check(p)
    return VariationsJob(exemplars, o.get("out", ""), p, outlines=outlines)


def check_types(flat: dict, where: str = "the job") -> dict:
    """``flat`` with its None values dropped, every name one of :data:`OPTIONS` and every value of
    its type; :class:`InputError` (one line) otherwise."""
    if not isinstance(flat, dict):
        raise InputError(f"{where} holds no JSON object; write the options as {{\"video\": ..., \"out\": ...}}")
    out: dict[str, Any] = {}
    for key, value in flat.items():
        name = str(key).replace("-", "_")
        kind = OPTIONS.get(name)
        if kind is None:
            raise InputError(f"unknown key '{key}' in {where}; use the batch options' names (video, outline, out, "
                             "gltf, bones, ...) and give --force/--dry-run/--quiet on the line")
        if value is None:
            continue
        ok = (isinstance(value, list) and all(isinstance(v, str) for v in value) if kind is list else
              isinstance(value, bool) if kind is bool else
              isinstance(value, int) and not isinstance(value, bool) if kind is int else
              isinstance(value, (int, float)) and not isinstance(value, bool) if kind is float else
              isinstance(value, str))
        if not ok:
            want = {bool: "true or false", int: "a whole number", float: "a number",
                    list: "a list of file names"}.get(kind, "a string")
            raise InputError(f"'{key}' in {where} is {json_type(value)}; give {want}")
        out[name] = value
    return out


def outputs_from(o: dict) -> JobOutputs:
    """The :class:`JobOutputs` of the options ``o``: the engine preset fills the game options not
    given, and its formats when none is; what needs the Blender outputs without one is refused."""
    bones = o.get("bones")
    if bones is not None and bones < 1:
        raise InputError(f"--bones {bones}: give at least 1 (e.g. 64), or drop it for every bone")
    engine = o.get("engine") or ""
    if engine:
        check(GameSettings(engine=engine))
    game = preset(engine, bones=bones, lods=o.get("lods"), loop_s=o.get("loop"),
                  pivot_painter=o.get("pivot_painter"), bone_texture=o.get("bone_texture"),
                  collision=o.get("collision"), viewer=o.get("viewer"), impostor=o.get("impostor"))
    formats = tuple(f.flag for f in FORMATS if o.get(f.flag))
    if engine and not formats:
        formats = tuple(f.flag for f in FORMATS if f.flag in game.formats)
    any_file = bool(formats)
    if bones is not None and not any_file:
        raise InputError(f"--bones cuts the rig of the Blender outputs; add one of {FORMAT_FLAGS}")
    if not spec(GameSettings, "lods").ok(game.lods):
        raise InputError(f"--lods {game.lods}: give a number of levels, {spec(GameSettings, 'lods').describe()}, e.g. 3")
    if game.viewer and "gltf" not in formats:
        raise InputError("--viewer plays tree.glb; add --gltf (or use --engine web)")
    for on, flag in ((game.lods > 1, "--lods"), (game.pivot_painter, "--pivot-painter"),
                     (game.bone_texture, "--bone-texture"), (game.collision, "--collision"),
                     (game.impostor, "--impostor"), (game.viewer, "--viewer")):
        if on and not any_file:
            raise InputError(f"{flag} comes with the Blender outputs; add one of {FORMAT_FLAGS}")
    if not spec(LoopSettings, "seconds").ok(game.loop_s):
        raise InputError(f"--loop {game.loop_s}: give a number of seconds, {spec(LoopSettings, 'seconds').describe()}, "
                         "e.g. 10")
    if game.loop_s > 0 and not any_file:
        raise InputError(f"--loop cuts the animation of the Blender outputs; add one of {FORMAT_FLAGS}")
    photos = tuple(o.get("bark_image") or ())
    given = [k for k in ("moss", "lichen", "bark_scale") if o.get(k) is not None]
    if given and not photos:
        raise InputError(f"--{given[0].replace('_', '-')} shapes the bark made from photos; add --bark-image PHOTO")
    d = BarkPhotoParams()
    bark = BarkPhotoParams(moss=o.get("moss", d.moss), lichen=o.get("lichen", d.lichen),
                           scale_cm=o.get("bark_scale", d.scale_cm))
    check(bark)
    billboard = o.get("billboard") or 0
    if billboard and not BILLBOARD_PX[0] <= billboard <= BILLBOARD_PX[1]:
        raise InputError(f"--billboard {billboard}: give the billboard's pixels on its longer side, "
                         f"{BILLBOARD_PX[0]}..{BILLBOARD_PX[1]}, e.g. 512")
    return JobOutputs(formats, game, o.get("leaf_image"), bool(o.get("npz")), not o.get("no_video"), photos, bark,
                      int(billboard))


def settings_of(o: dict) -> Settings:
    """The reconstruction's :class:`Settings` of the options ``o`` (checked)."""
    flat = {SETTINGS[k]: v for k, v in o.items() if k in SETTINGS}
    flat.update(conifer=bool(o.get("conifer")), fit_branches=not o.get("no_branch_fit"),
                leaves=not o.get("no_leaves"))
    s = settings_from_flat(flat)
    check_settings(s)
    return s


def request_of(o: dict, has_video: bool, loop_s: float = 0.0) -> GenerateRequest:
    """The :class:`GenerateRequest` of the options ``o`` (``generate`` trees; checked), each tree
    swaying in a loop of ``loop_s`` seconds (0: none; the outputs' loop, an engine preset's too)."""
    d = GenerateRequest()
    req = GenerateRequest(count=o["generate"], species=o.get("species"), envelope=o.get("envelope"),
                          wind=o.get("wind", d.wind), audio=o.get("audio"), seed=o.get("seed", d.seed),
                          nodes=o.get("nodes", d.nodes), frames_out=o.get("frames_out"), seconds=o.get("seconds"),
                          height_m=o.get("height", d.height_m),
                          leaf_density=0.0 if o.get("no_leaves") else o.get("leaf_density", d.leaf_density),
                          twig_depth=o.get("twigs", d.twig_depth), loop_s=float(loop_s),
                          envelope_variation=o.get("envelope_variation", d.envelope_variation),
                          allometry=bool(o.get("allometry")), cuts=tuple(o.get("cut") or ()))
    check_request(req, has_video=has_video)
    return req


def from_flat(flat: dict, where: str = "the job") -> Job:
    """The job the batch options ``flat`` (:data:`OPTIONS` by name; None: the default) describe
    (module docstring): ``tree`` → :class:`ExportJob`; ``video`` a photo → :class:`PhotoJob`;
    ``video`` → :class:`ReconstructJob`; ``generate`` alone → :class:`GenerateJob`. Wrong names,
    types, values and combinations are one-line :class:`InputError`\\ s (``where`` names the file in
    them). ``out`` may be empty (the panel builds in its scene)."""
    o = check_types(flat, where)
    if o.get("variations") is not None:
        return variations_of(o)
    if o.get("exemplars") or o.get("exemplar_outlines"):
        raise InputError("--exemplars are the pictures --variations N is made from; add --variations N")
    outputs = outputs_from(o)
    out = o.get("out", "")
    if o.get("tree"):
        if o.get("video") or o.get("outline") or o.get("generate") is not None:
            raise InputError("--tree builds the outputs of a saved tree; drop the VIDEO, --outline and --generate")
        if not outputs.blender:
            raise InputError(f"--tree builds the Blender outputs; add one of {FORMAT_FLAGS} or --billboard PX")
        if VIDEO_BARK in outputs.bark_images:
            raise InputError("--bark-image video takes the bark from a video's trunk as it is traced; with --tree "
                             "give a photo of bark")
        return ExportJob(o["tree"], out, outputs)
    video = o.get("video")
    if video is None:
        if o.get("generate") is None:
            raise InputError("no VIDEO given: give VIDEO --outline OUTLINE.json, or --generate N --species NAME "
                             "to grow new trees")
        if VIDEO_BARK in outputs.bark_images:
            raise InputError("--bark-image video takes the bark from the reconstructed video's trunk; give a photo "
                             "of bark to grow trees without a video")
        d = Settings()
        return GenerateJob(request_of(o, False, outputs.game.loop_s), out, outputs,
                           o.get("curliness", d.curliness), o.get("bark", d.bark), o.get("forks", d.forks),
                           o.get("bark_relief", d.relief_cm))
    photo = is_photo(video)
    if o.get("generate") is None:
        allowed = ("species", "seconds") if photo else ()
        for opt in GENERATION_ONLY:
            if o.get(opt) is not None and opt not in allowed:
                raise InputError(f"--{opt.replace('_', '-')} only applies with --generate N; add it or drop the option")
    if not o.get("outline"):
        raise InputError("give the tree's outline in frame 1 with --outline OUTLINE.json|MASK.png|auto")
    settings = settings_of(o)
    generate = request_of(o, True, outputs.game.loop_s) if o.get("generate") is not None else None
    if photo:
        pm = PhotoMotion()
        motion = PhotoMotion(species=o.get("species") or "", seconds=o.get("seconds", pm.seconds),
                             wind=o.get("wind", pm.wind), seed=o.get("seed", pm.seed))
        check(motion)                                 # --seconds and --wind within PhotoMotion's ranges
        return PhotoJob(video, o["outline"], out, settings, outputs, generate, motion)
    return ReconstructJob(video, o["outline"], out, settings, outputs, generate)


def _outputs_flat(out: JobOutputs) -> dict:
    g = out.game
    flat: dict[str, Any] = {f.flag: f.flag in out.formats for f in FORMATS}
    flat.update(engine=g.engine or None, bones=g.bones or None, lods=g.lods, loop=g.loop_s,
                pivot_painter=g.pivot_painter, bone_texture=g.bone_texture, collision=g.collision,
                viewer=g.viewer, impostor=g.impostor, leaf_image=out.leaf_image, npz=out.npz,
                no_video=not out.overlay_video, billboard=out.billboard or None)
    if out.bark_images:
        flat.update(bark_image=list(out.bark_images), moss=float(out.bark.moss), lichen=float(out.bark.lichen),
                    bark_scale=float(out.bark.scale_cm))
    return flat


def _settings_flat(s: Settings) -> dict:
    leaves = s.leaves
    flat = {"levels": s.levels, "frames": s.frames, "skeleton": s.skeleton, "scale": float(s.scale),
            "form": s.form, "limbs": s.limbs, "limb_species": s.limb_species, "depth": s.depth,
            "solver": s.motion.solver, "height": float(s.height_m), "twigs": int(s.twigs.depth),
            "no_branch_fit": not s.fit_branches, "curliness": float(s.curliness), "bark": s.bark,
            "forks": s.forks, "bark_relief": float(s.relief_cm) or None,
            "no_leaves": leaves is None, "fold_alpha": float(s.fold_alpha), "candidates": int(s.lift.candidates),
            "sigma_track": float(s.motion.sigma_track), "sigma_shape": float(s.motion.sigma_shape),
            "max_step": float(s.motion.max_step), "max_total": float(s.motion.max_total)}
    if leaves is not None:
        flat.update(leaf_density=float(leaves.density), leaf_cards=int(leaves.cards),
                    flutter_hz=float(leaves.flutter_hz), leaf_colour=leaves.colour,
                    flutter_gain=float(leaves.flutter_gain), max_leaf_clusters=int(leaves.max_clusters))
    return flat


def _request_flat(r: GenerateRequest) -> dict:
    return {"generate": r.count, "species": r.species, "envelope": r.envelope, "wind": float(r.wind),
            "audio": r.audio, "seed": r.seed, "nodes": r.nodes, "frames_out": r.frames_out, "seconds": r.seconds,
            "envelope_variation": float(r.envelope_variation), "allometry": bool(r.allometry) or None,
            "cut": list(r.cuts) or None}


def to_flat(job: Job) -> dict:
    """The batch options of ``job`` by name (None where the default holds): what :func:`from_flat`
    reads back into the same job, what a job file holds and what the report records."""
    flat: dict[str, Any] = {"out": job.out or None}
    if isinstance(job, VariationsJob):
        flat.update(variations=job.params.count, exemplars=list(job.exemplars), seed=job.params.seed,
                    exemplar_outlines=list(job.outlines) or None)
        return flat
    flat.update(_outputs_flat(job.outputs))
    if isinstance(job, ExportJob):
        flat["tree"] = job.tree
    elif isinstance(job, GenerateJob):
        flat.update(_request_flat(job.request), height=float(job.request.height_m),
                    twigs=int(job.request.twig_depth), curliness=float(job.curliness), bark=job.bark,
                    forks=job.forks, bark_relief=float(job.relief_cm) or None)
        if job.request.leaf_density == 0.0:
            flat["no_leaves"] = True
        else:
            flat["leaf_density"] = float(job.request.leaf_density)
    else:
        flat.update(video=job.video, outline=job.outline, **_settings_flat(job.settings))
        if job.generate is not None:
            flat.update(_request_flat(job.generate))
        if isinstance(job, PhotoJob):
            m = job.motion
            flat.update(species=m.species or None, seconds=float(m.seconds), wind=float(m.wind), seed=m.seed)
    return {k: v for k, v in flat.items() if v is not None}


def side_files(settings: dict) -> list[str]:
    """The files ``settings`` (:func:`settings_doc`) names in :data:`SIDE_FILES`, in order, as the
    job reads them: a bark folder's photos (:func:`.detail.bark_photo.bark_photo_files`), a cut's
    file (:func:`.generate.cuts.parse_cut_spec`); names that are no file (``video``, a preset, a
    folder without photos, a bad cut) are left out: the run names those."""
    import os

    from .detail.bark_photo import bark_photo_files
    from .generate.cuts import parse_cut_spec
    out: list[str] = []
    for key in SIDE_FILES:
        value = settings.get(key)
        for item in value if isinstance(value, list) else [value] if value else []:
            try:
                path = parse_cut_spec(item).path if key == "cut" else str(item)
                out += bark_photo_files(path) if key == "bark_image" and os.path.isdir(path) else [path]
            except InputError:
                continue
    return [p for p in out if os.path.isfile(p)]


def settings_doc(job: Job) -> dict:
    """The job's settings as its report records them (and hashes them): :func:`to_flat` without
    where it reads and writes, sorted by name."""
    return {k: v for k, v in sorted(to_flat(job).items()) if k not in PLACES}


def to_argv(flat: dict, where: str = "the job") -> list[str]:
    """The batch command line of the options ``flat`` (:data:`OPTIONS` by name, checked by
    :func:`check_types`; ``where`` names them in its errors): ``VIDEO`` first, a switch as its
    flag when true, the rest ``--name value``."""
    o = check_types(flat, where)
    argv: list[str] = [str(o["video"])] if "video" in o else []
    for key, value in o.items():
        if key == "video":
            continue
        flag = "--" + key.replace("_", "-")
        if OPTIONS[key] is list:
            for item in value:
                argv += [flag, str(item)]
        elif OPTIONS[key] is bool:
            argv += [flag] if value else []
        else:
            argv += [flag, repr(value) if isinstance(value, float) else str(value)]
    return argv
