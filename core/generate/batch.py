"""The batch job's generation flow (``batch.py --generate N``): N new animated trees of one species,
each in its own folder, and a ``generated.json`` index. No Blender here: the caller passes a
``write_files(tree, folder)`` that builds the tree in a scene and exports it (``operators/scene/outputs``).

Layout of ``DIR`` (``FOLDER_FORMAT``):

    DIR/generated.json              the run's settings and, per tree, seed, species, envelope,
                                    bones, leaf clusters, files (paths relative to DIR)
    DIR/tree_000/tree3d.npz         the animated tree (core/tree3d.py), always
    DIR/tree_000/tree.glb ...       the export files asked for (tree.fbx/.usdc/.glb/.blend, preview.png)
    DIR/tree_001/ ...

Tree ``i`` (0-based) grows with seed ``seed + i``: the same command gives the same trees.
"""
from __future__ import annotations

import json
import os
import tempfile
import time
from dataclasses import dataclass

import numpy as np

from ..detail.twigs import TwigParams
from ..errors import InputError
from ..loop import LoopSettings
from ..params import check, param, same_as
from ..progress import ProgressFn
from .cuts import parse_cut_spec
from .growth import GrowParams

MAX_TREES = 1000
FOLDER_FORMAT = "tree_{:03d}"
INDEX = "generated.json"
SPECIES_FILE = "species.json"          # written by a run with a video (the fitted species)
TREE_FILE = "tree3d.npz"


@dataclass
class GenerateRequest:
    """What ``--generate`` asks for. ``species``: a library name or a species file (None: fit it
    from the reconstruction); ``envelope``: a topiary name, an image path or None (the
    reconstruction's envelope, else ``default_envelope``); ``frames_out`` / ``seconds`` the length
    of each animation (None: the species' source clip); ``height_m`` of the envelope;
    ``leaf_density`` 0 for bare trees; ``twig_depth`` generations of twigs (0: none); ``loop_s`` > 0:
    each tree sways in a loop of that many seconds by construction (``GrowParams.loop_s``);
    ``envelope_variation`` 0..1: each tree in its own crown around the envelope; ``allometry``: the
    forks' angles by Holton's rule (both ``GrowParams``); ``cuts`` tree-cuts every tree must contain,
    ``FILE`` (where it fits) or ``FILE@X,Y,Z`` (its base at that point, metres from the tree's
    base; :func:`.cuts.parse_cut_spec`)."""

    count: int = param(1, 1, MAX_TREES, what="--generate")
    species: str | None = None
    envelope: str | None = None
    wind: float = param(1.0, 0.0, what="--wind")
    audio: str | None = None
    seed: int = param(0, 0, what="--seed")
    nodes: int = param(200, 4, what="--nodes")
    frames_out: int | None = None
    seconds: float | None = None
    height_m: float = param(10.0, 0.0, 1000.0, lo_open=True, what="--height", unit="m")
    leaf_density: float = 1.0
    twig_depth: int = same_as(TwigParams, "depth")
    loop_s: float = same_as(LoopSettings, "seconds")
    envelope_variation: float = same_as(GrowParams, "envelope_variation")
    allometry: bool = False
    cuts: tuple[str, ...] = ()


def tree_folders(count: int) -> list[str]:
    return [FOLDER_FORMAT.format(i) for i in range(int(count))]


def planned_files(req: GenerateRequest, export_names: list[str], with_species: bool = False) -> list[str]:
    """Every path (relative to DIR) the run will write, for the overwrite check before any work."""
    names = [INDEX] + ([SPECIES_FILE] if with_species else [])
    for folder in tree_folders(req.count):
        names += [os.path.join(folder, n) for n in [TREE_FILE, *export_names]]
    return names


def check_request(req: GenerateRequest, has_video: bool) -> None:
    """Refuse bad numbers and impossible combinations (:class:`InputError`, one sentence with the fix)."""
    if not MAX_TREES >= req.count >= 1:
        raise InputError(f"--generate {req.count}: give a number of trees from 1 to {MAX_TREES}")
    if req.species is None and not has_video:
        raise InputError("--generate needs a species: add --species broad|sparse|conifer|FILE.json, "
                         "or give a VIDEO with --outline to fit one")
    if req.species is not None and has_video:
        raise InputError("--species and a VIDEO both given: drop --species to generate from the video's tree, "
                         "or drop the VIDEO to use the species")
    if not (np.isfinite(req.wind) and req.wind >= 0):
        raise InputError(f"--wind {req.wind} must be a number >= 0 (1 = as in the example, 2 = twice the sway)")
    if int(req.nodes) < 4:
        raise InputError(f"--nodes {req.nodes} is too small; give at least 4 (default 200)")
    if req.frames_out is not None and req.seconds is not None:
        raise InputError("--frames-out and --seconds both given; keep one")
    if req.frames_out is not None and not req.frames_out >= 1:
        raise InputError(f"--frames-out {req.frames_out} must be at least 1")
    if req.seconds is not None and not (np.isfinite(req.seconds) and req.seconds > 0):
        raise InputError(f"--seconds {req.seconds} must be positive, e.g. 10")
    if not (np.isfinite(req.height_m) and req.height_m > 0):
        raise InputError(f"--height {req.height_m} must be positive metres, e.g. 10")
    if not 0 <= req.leaf_density <= 1:
        raise InputError(f"--leaf-density {req.leaf_density} must be in [0, 1]; 0 or --no-leaves for bare trees")
    if req.seed < 0:
        raise InputError(f"--seed {req.seed} must be >= 0")
    for c in req.cuts:
        parse_cut_spec(c)
    check(req)                                   # --twigs (and the ranged fields above) in range


def load_species_spec(spec: str):
    """``(SpeciesModel, label)`` from a library name (``species/NAME.json``) or a species file."""
    from .species import load_species, species_library
    lib = species_library()
    if spec in lib:
        return load_species(lib[spec]), spec
    if spec.lower().endswith(".json") or os.path.sep in spec or os.path.exists(spec):
        return load_species(spec), os.path.abspath(spec)
    raise InputError(f"unknown species '{spec}'; choose one of {', '.join(lib) or '(none shipped)'} "
                     "or give a species .json file")


def default_envelope(model) -> str:
    """The shape used when a species file (which has no outline) gets no ``--envelope``:
    a triangle for conifers, a circle for the others."""
    return "triangle" if model.conifer else "circle"


def make_envelope(spec: str, height_m: float):
    """``(envelope, label)`` from a topiary name or an image path, ``height_m`` metres tall."""
    from .envelopes import SHAPES, envelope_from_any
    if spec.lower() in SHAPES:
        return envelope_from_any(spec.lower(), height_m), spec.lower()
    if not os.path.splitext(spec)[1]:
        raise InputError(f"unknown envelope '{spec}'; choose one of {', '.join(SHAPES)} or give a silhouette image")
    return envelope_from_any(spec, height_m), os.path.abspath(spec)


def check_audio(path: str) -> None:
    """Read ``path`` once (missing, non-WAV, empty or silent → :class:`InputError`)."""
    from .wind import audio_envelope
    audio_envelope(path, 24.0, 24)


def n_frames_for(req: GenerateRequest, model) -> int:
    if req.frames_out is not None:
        return int(req.frames_out)
    if req.seconds is not None:
        return max(1, int(round(req.seconds * model.fps)))
    return int(model.n_frames)


def _write_json(path: str, data) -> None:
    from ..fileio import publish
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".json", dir=os.path.dirname(os.path.abspath(path)))
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(data, fh, indent=1)
            fh.write("\n")
        publish(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def generate_trees(model, species_label: str, envelope, envelope_label: str, req: GenerateRequest,
                   out_dir: str, write_files=None, progress: ProgressFn | None = None, log=None) -> list[dict]:
    """Grow ``req.count`` trees of ``model`` in ``envelope`` into ``out_dir/tree_XXX/`` (tree3d.npz
    and whatever ``write_files(tree, folder) -> {format: path}`` writes), then ``generated.json``.
    Returns the per-tree entries of ``generated.json``."""
    from ..tree3d import save_tree
    from .growth import grow_tree
    log = log or (lambda m: None)
    n_frames = n_frames_for(req, model)
    entries = []
    for i, folder in enumerate(tree_folders(req.count)):
        seed = int(req.seed) + i
        t0 = time.perf_counter()
        log(f"[generate] tree {i + 1}/{req.count}: seed {seed}")
        params = GrowParams(seed=seed, height_m=None, node_budget=int(req.nodes), n_frames=n_frames,
                            wind=float(req.wind), leaf_density=float(req.leaf_density),
                            twig_depth=int(req.twig_depth), loop_s=float(req.loop_s),
                            envelope_variation=float(req.envelope_variation), allometry=bool(req.allometry),
                            cuts=tuple(parse_cut_spec(c) for c in req.cuts), name=f"{model.name}_{seed}")
        tree = grow_tree(model, envelope, params, audio=req.audio, progress=progress)
        d = os.path.join(out_dir, folder)
        os.makedirs(d, exist_ok=True)
        save_tree(os.path.join(d, TREE_FILE), tree)
        written = write_files(tree, d) if write_files is not None else {}
        paths = [q for v in written.values() for q in (v if isinstance(v, (list, tuple)) else [v])]   # engine files: lists
        files = [os.path.join(folder, TREE_FILE)] + [os.path.relpath(q, out_dir) for q in paths]
        entries.append({"folder": folder, "seed": seed, "species": species_label, "envelope": envelope_label,
                        "bones": int(tree.n_nodes - 1), "leaf_clusters": int(tree.leaves.count if tree.leaves else 0),
                        "frames": int(tree.n_frames), "stopped": tree.meta.get("stopped"),
                        "files": [f.replace(os.sep, "/") for f in files],
                        "seconds": round(time.perf_counter() - t0, 3)})
    index = {"format": "tree_from_video.generated", "version": 1, "species": species_label,
             "envelope": envelope_label, "count": int(req.count), "seed": int(req.seed), "wind": float(req.wind),
             "audio": os.path.abspath(req.audio) if req.audio else None, "nodes": int(req.nodes),
             "frames": n_frames, "fps": float(model.fps), "height_m": float(np.max(envelope.z)),
             "leaf_density": float(req.leaf_density), "twig_depth": int(req.twig_depth), "trees": entries}
    _write_json(os.path.join(out_dir, INDEX), index)
    return entries
