"""The end-to-end pipeline: a video and an outline in, an animated 3D tree with its details out.

:class:`Settings` are the product's defaults (those of the panel and the batch options);
:func:`run` the 2D stages (:mod:`.reconstruct.run`), :func:`build_3d` the 3D lift, the motion,
the branch widths from frame 1, the twigs and the leaves (:mod:`.reconstruct`, :mod:`.detail`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from .detail.albedo import SceneLight, bark_colour, hidden_bark, scene_light, trunk_pixels
from .detail.branch_mesh import MeshParams, check_params
from .detail.fronds import fit_fronds
from .detail.leaf_clusters import LeafParams, check_leaf_params, leaves_for_form
from .detail.leaf_seeds import place_leaves
from .detail.twigs import TwigParams, add_twigs, check_twig_params
from .envelope import envelope_to_meta
from .errors import InputError
from .generate.allometry import allometry_report
from .generate.limbs import LIMB_SOURCES, grown_limbs, limb_species
from .generate.photo import PhotoMotion, species_for
from .generate.photo import sway as photo_sway
from .generate.photo_crown import CrownFill, fill_crown
from .meta import TreeMeta
from .params import check, param, same_as
from .progress import ProgressFn, expected_seconds, stage_split, sub_progress
from .reconstruct.branch_fit import fit_to_video, measure_branches, tree_map
from .reconstruct.foreground import foreground
from .reconstruct.learned_depth import DEPTH_SOURCES, shared_net
from .reconstruct.lift import LiftParams, lift
from .reconstruct.motion import MotionParams, fit_warning, motion_fit, solve_motion
from .reconstruct.run import (
    SKELETON_KINDS,
    STAGE_COSTS_2D,
    ReconstructSettings,
    Result,
    check_reconstruct,
    count_outlines,
    frame_one,
    track_video,
)
from .reconstruct.run import run as run_2d
from .reconstruct.run import run_all as run_2d_all
from .reconstruct.skeleton2d import Skeleton2D
from .reconstruct.tracks import detect_corners
from .reconstruct.video import open_video, parse_frame_range
from .topology import branching_level
from .tree3d import Tree3D, image_to_plane, pipe_radii, plane_to_image, uneven_times

__all__ = ["SKELETON_KINDS", "STAGE_COSTS_3D", "Result", "Settings", "add_leaves", "build_3d", "build_shot",
           "check_settings", "clip_frames", "count_outlines", "first_frame", "run", "run_all", "share_2d", "track_video",
           "with_limbs"]

#: Seconds a 3D stage takes ≈ fixed + per frame × frames ``(fixed s, s per frame)``, measured like
#: :data:`.reconstruct.run.STAGE_COSTS_2D` (sample_videos/broad and sparse, 12–180 frames, wheel and
#: Blender 4.3, 2 cores): the branch fit 0.03–0.07 s and the lift 0.08–0.39 s whatever the length
#: (together "lift"); the motion, since each frame is one sparse solve (:mod:`.reconstruct.rotation_solve`),
#: 1.5–2 ms a frame for the broad sample's 185 nodes (0.3 s at 180 frames; 13 ms a frame before);
#: twigs and leaves 0.03–0.1 s.
STAGE_COSTS_3D = {"lift": (0.23, 0.0), "motion": (0.0, 0.002), "details": (0.04, 0.0)}


@dataclass
class Settings(ReconstructSettings):
    """Everything a run needs besides the input files: the 2D stages' settings
    (:class:`ReconstructSettings`) and those of the 3D tree. The defaults are the product's: the
    panel and the batch options read them (and their ranges) from these dataclasses."""

    lift: LiftParams = field(default_factory=LiftParams)
    motion: MotionParams = field(default_factory=MotionParams)
    height_m: float = param(10.0, 0.0, 1000.0, lo_open=True, what="tree height", unit="m")
    tip_radius: float = 0.0025      # branch radius at the tips, share of the height (pipe model)
    pipe_exponent: float = 2.0      # r_parent^e = Σ r_child^e
    twigs: TwigParams = field(default_factory=TwigParams)
    curliness: float = same_as(MeshParams, "curliness")   # branch mesh (recorded in meta["mesh"])
    bark: str = same_as(MeshParams, "bark")               # branch mesh (recorded in meta["mesh"])
    forks: str = same_as(MeshParams, "forks")             # branch mesh (recorded in meta["mesh"])
    relief_cm: float = same_as(MeshParams, "relief_cm")   # branch mesh (recorded in meta["mesh"])
    leaves: LeafParams | None = field(default_factory=LeafParams)   # None: bare branches
    fit_branches: bool = True       # branch widths and centre lines measured in frame 1 (branch_fit)
    # the crown's limbs: traced, or grown from a species where the video shows no bark (generate.limbs)
    limbs: str = param("auto", choices=LIMB_SOURCES, what="limbs")
    limb_species: str = ""          # the species grown (library name or .json file; "": the form's own)
    # where the lift takes the depth one view cannot show (issue 35): the outline's surface of
    # revolution, or the network trained on synthetic trees (reconstruct.learned_depth)
    depth: str = param("learned", choices=DEPTH_SOURCES, what="depth source")


#: flat option names (the batch's, the panel's, the API's keywords) that set a nested setting
NESTED = {"twigs": ("twigs", "depth"), "twig_depth": ("twigs", "depth"), "solver": ("motion", "solver"),
          "sigma_track": ("motion", "sigma_track"), "sigma_shape": ("motion", "sigma_shape"),
          "max_step": ("motion", "max_step"), "max_total": ("motion", "max_total"),
          "candidates": ("lift", "candidates"), "leaf_density": ("leaves", "density"),
          "leaf_cards": ("leaves", "cards"), "flutter_hz": ("leaves", "flutter_hz"),
          "flutter_gain": ("leaves", "flutter_gain"), "max_leaf_clusters": ("leaves", "max_clusters"),
          "leaf_colour": ("leaves", "colour")}
#: flat switches: ``conifer`` (the form when it is ``auto``), ``leaves`` (False: bare branches)
SWITCHES = ("conifer", "leaves")


def from_flat(flat: dict) -> Settings:
    """The one way flat options become :class:`Settings`, for the batch job, the panel and the API:
    a field of ``Settings`` by its name (``levels``, ``frames``, ``height_m``, ``form``…), a nested
    one by its flat name (:data:`NESTED`: ``twigs=2``, ``solver``, ``leaf_density``…; a whole
    ``TwigParams`` or ``LeafParams`` under ``twigs`` / ``leaves`` too), ``conifer=True`` (the
    conifer form unless a form is given) and ``leaves=False`` (bare branches). Unset names keep the
    product's defaults; an unknown name is an :class:`InputError`. Not range-checked here
    (:func:`check_settings`)."""
    s = Settings()
    names = {f for f in s.__dataclass_fields__}
    unknown = [k for k in flat if k not in names and k not in NESTED and k not in SWITCHES]
    if unknown:
        raise InputError(f"unknown setting '{unknown[0]}'; use one of {', '.join(sorted(names | set(NESTED)))}")
    leaves = flat.get("leaves", True)
    if isinstance(leaves, LeafParams):
        s.leaves = leaves
    elif leaves is None or not leaves:
        s.leaves = None
    for key, value in flat.items():
        if key in SWITCHES or (key in ("twigs", "leaves") and not isinstance(value, (int, float, str))):
            continue
        if key in NESTED:
            group, attr = NESTED[key]
            target = getattr(s, group)
            if target is not None:                      # leaf options of a bare tree are moot
                setattr(target, attr, int(value) if attr == "depth" else value)
        else:
            setattr(s, key, value)
    if isinstance(flat.get("twigs"), TwigParams):
        s.twigs = flat["twigs"]
    if flat.get("conifer") and flat.get("form", "auto") == "auto":
        s.form = "conifer"
    return s


def check_settings(s: Settings) -> None:
    """Raise :class:`InputError` for the first setting out of range (2D stages, twigs, mesh, leaves)."""
    check_reconstruct(s)
    check(s.motion)
    check(s.lift)
    if not s.height_m > 0:
        raise InputError(f"tree height {s.height_m} m is not positive; give e.g. 10")
    check_twig_params(s.twigs)
    check_params(MeshParams(curliness=s.curliness, bark=s.bark, forks=s.forks, relief_cm=s.relief_cm))
    if s.leaves is not None:
        check_leaf_params(s.leaves)
    if s.limb_species and s.limbs != "trace":
        limb_species(s.limb_species, "broadleaf")         # a missing or broken species file fails now


def run(video: str, outline_path, settings: Settings | None = None,
        progress: ProgressFn | None = None) -> Result:
    """Video + outline → tracks, hierarchy and moving 2D skeleton (:func:`.reconstruct.run.run`),
    after checking every setting (also those of :func:`build_3d`, so nothing fails after the
    tracking). Raises InputError on bad input."""
    s = settings or Settings()
    check_settings(s)
    return with_limbs(run_2d(video, outline_path, s, progress), s)


def run_all(video: str, outline_path, settings: Settings | None = None,
            progress: ProgressFn | None = None) -> list[Result]:
    """:func:`run` for every tree the outline holds (a .json of several polygons, a mask of several
    components; :func:`.reconstruct.run.run_all`): one decode and one tracking pass, one
    :class:`Result` per tree in the outline's order."""
    s = settings or Settings()
    check_settings(s)
    return [with_limbs(r, s) for r in run_2d_all(video, outline_path, s, progress)]


def with_limbs(res: Result, s: Settings) -> Result:
    """``res`` with its crown's limbs grown from a species (:func:`.generate.limbs.grown_limbs`)
    when ``s.limbs`` is "grow", or "auto" and the trace saw no bark in the crown; palms keep
    their traced fronds and the paper's skeleton its own."""
    sk = res.skeleton
    if s.limbs == "trace" or (s.limbs == "auto" and sk.limbs_seen) or sk.kind != "traced":
        return res
    if res.form == "palm":
        note = "a palm's crown is fronds: they are traced, not grown"
        return replace(res, skeleton=replace(sk, warnings=[*sk.warnings, note]))
    return replace(res, skeleton=grown_limbs(res, limb_species(s.limb_species, res.form), int(s.twigs.seed)))


def clip_frames(video: str, settings: Settings | None = None) -> int:
    """Frames :func:`run` will read from ``video`` with ``settings`` (their frame range)."""
    s = settings or Settings()
    start, stop = parse_frame_range(s.frames, open_video(video, s.scale).frame_count)
    return stop - start


def share_2d(n_frames: int) -> float:
    """Share of a reconstruction's time (:func:`run` then :func:`build_3d`) the 2D stages take for a
    clip of ``n_frames`` (from :data:`STAGE_COSTS_2D` and :data:`STAGE_COSTS_3D`): where a progress
    bar over both should put the end of :func:`run`."""
    t2 = sum(expected_seconds(STAGE_COSTS_2D, n_frames).values())
    t3 = sum(expected_seconds(STAGE_COSTS_3D, n_frames).values())
    return t2 / (t2 + t3)


#: frame 1's tree map is not used when under this share of the outline differs from the background
#: around it (other trees behind the tree: a real photo's 1.4 %; the samples 38-76 %, a sparse real
#: crown against the sky 20 %)
MIN_TREE_SHARE = 0.05


def trusted_tree_map(frame: np.ndarray, mask: np.ndarray):
    """``(tree map or None, share or None)``: frame 1's tree map (:func:`.reconstruct.branch_fit.tree_map`)
    when at least :data:`MIN_TREE_SHARE` of the outline differs from what lies around it, else None
    (the background looks like the tree); ``share`` what it told apart (None without a map)."""
    tmap = tree_map(frame, mask)
    if tmap is None:
        return None, None
    return (tmap if tmap.share >= MIN_TREE_SHARE else None), tmap.share


def tree_warnings(res: Result, tree: Tree3D) -> list[str]:
    """The run's warnings, and the 3D motion's when it strays from the measured 2D motion
    (``meta["motion_fit"]``, :func:`.reconstruct.motion.fit_warning`): what the batch run and the
    panel report for a reconstructed tree."""
    stray = fit_warning(tree.meta["motion_fit"]) if "motion_fit" in tree.meta else None
    tm = tree.meta.get("tree_map")
    unseen = None
    if tm is not None and not tm.get("used", True):
        unseen = (f"frame 1's tree cannot be told from what lies around its outline (only {tm['share']:.1%} of "
                  "the outline differs from it: other trees behind it?): branch widths, leaf colours and twigs "
                  "take the whole outline; draw the outline closer to the tree or use a frame with sky around it")
    return [*res.warnings, *([stray] if stray else []), *([unseen] if unseen else [])]


def build_3d(res: Result, s: Settings | None = None, name: str = "Tree",
             progress: ProgressFn | None = None, metres_per_px: float | None = None,
             photo: PhotoMotion | None = None) -> Tree3D:
    """Lift the 2D skeleton to 3D and solve its motion; the tree in metres, ``height_m`` tall (or
    at ``metres_per_px``: a shot of several trees shares one scale, :func:`build_shot`). With
    ``photo`` (a one-frame video: a photo) the motion is a species' sway instead (:mod:`.generate.photo`)."""
    s = s or Settings()
    if not s.height_m > 0:
        raise InputError(f"tree height {s.height_m} m is not positive; give e.g. 10")
    sk = res.skeleton
    parts = stage_split(progress, expected_seconds(STAGE_COSTS_3D, sk.nodes2d.shape[0]))
    frame = first_frame(res)
    fit = radius_px = tmap = tmap_share = None
    if frame is not None:               # frame 1 against its background: branch widths, foreground
        tmap, tmap_share = trusted_tree_map(frame, res.outline.mask)
        if tmap is not None and s.fit_branches:
            fit = measure_branches(sk.parents, sk.nodes2d[0], tmap)
            if sk.kind == "grown":            # the frame shows the trunk, not limbs grown behind the leaves
                fit = replace(fit, width_px=np.where(sk.level == 0, fit.width_px, np.nan))
            vf = fit_to_video(sk.parents, sk.level, sk.nodes2d[0], fit, s.pipe_exponent, sk.trunk_width_px)
            radius_px = vf.radius_px
            if radius_px is not None:               # onto the branches' centre lines, every frame
                sk = replace(sk, nodes2d=(sk.nodes2d + vf.shift_px[None]).astype(np.float32))
    lift_params = s.lift if s.lift.conifer or res.form != "conifer" else replace(s.lift, conifer=True)
    if photo is not None:               # no measured motion to keep to: the leader stays in the plane
        lift_params = replace(lift_params, leader=True)
    depth = fit_err = None
    if s.depth == "learned" and frame is not None:      # frame 1's depths from the network
        net = shared_net()
        depth = net.predict(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), res.outline.mask,
                            sk.nodes2d[0].astype(np.float64), sk.parents)
        fit_err = net.fit
    lifted = lift(sk, res.outline, lift_params, parts["lift"], depth=depth, fit=fit_err)
    base = sk.nodes2d[0, 0].astype(float)
    targets = image_to_plane(sk.nodes2d.astype(float), base)[..., [0, 2]]
    mo = solve_motion(lifted.nodes, sk.parents, sk.level, targets, s.motion.for_form(lift_params.conifer),
                      parts["motion"], sk.confidence)
    nodes, times = mo.nodes, uneven_times(sk.times, sk.fps)
    followed = None if photo is not None else motion_fit(mo.nodes, sk.parents, targets, sk.confidence).summary()
    fill = None
    if photo is not None:                         # a photo: its species' sway on the traced rest pose
        model = species_for(photo, res.form)
        rest = mo.nodes[0]
        if depth is not None and res.form != "palm":     # its crown grown where it shows no branches
            fill = fill_crown(sk.parents, rest, sk.nodes2d[0, 0], depth, res.outline.mask,
                              tmap.tree if tmap is not None else None, int(photo.seed))
            if fill.added:
                sk, rest = grown_skeleton(sk, fill), fill.rest
                if radius_px is not None:            # grown limbs as thin as the traced tips
                    tips = np.setdiff1d(np.arange(len(radius_px)), sk.parents[:len(radius_px)])
                    radius_px = np.concatenate([radius_px, np.full(fill.added, np.nanmin(radius_px[tips]))])
        nodes, times = photo_sway(model, sk.parents, rest, photo, sk.fps), None
    height_px = max(float(lifted.envelope.z.max()), float(lifted.nodes[:, 2].max()), 1.0)
    scale = s.height_m / height_px if metres_per_px is None else float(metres_per_px)
    if radius_px is not None:
        radius = (radius_px * scale).astype(np.float32)
    else:
        radius = pipe_radii(sk.parents, s.tip_radius * height_px * scale, s.pipe_exponent)
    meta: TreeMeta = {"height_px": height_px, "metres_per_px": scale, "solver": s.motion.solver,
            "conifer": lift_params.conifer, "form": res.form, "mu_deg": float(np.degrees(lifted.mu)),
            "envelope": envelope_to_meta(lifted.envelope, scale),
            "mesh": {"curliness": float(s.curliness), "bark": s.bark, "seed": int(s.twigs.seed), "forks": s.forks,
                     "relief_cm": float(s.relief_cm)},
            "limbs": sk.kind,                                    # traced from the video, or grown
            **({"photo": {"species": photo.species or model.name, "seconds": float(photo.seconds),
                          "wind": float(photo.wind), "seed": int(photo.seed),
                          **({"crown_fill": fill.meta()} if fill is not None else {})}} if photo is not None else {}),
            "depth": {"source": "learned" if depth is not None else "envelope",
                      "crown_scale": round(float(lifted.envelope.depth_scale), 4)},
            **({"motion_fit": followed} if followed is not None else {}),
            "base_px": [float(base[0]), float(base[1])],          # trunk base in frame 1 (x, y) px
            "video_size": [int(res.outline.mask.shape[1]), int(res.outline.mask.shape[0])]}
    if tmap_share is not None:
        meta["tree_map"] = {"share": round(float(tmap_share), 4), "used": tmap is not None}
    tree = Tree3D(sk.parents.copy(), (nodes * scale).astype(np.float32), radius, sk.level.copy(),
                  sk.fps, name, meta, times=times)
    if fit is not None:
        meta["branch_fit"] = {"measured": fit.n_measured, "radii": radius_px is not None,
                              "trusted": int(vf.trusted.sum()),
                              "tree_share": round(fit.tree_share, 4)}
    tree_px = tmap.tree if tmap is not None else None
    fg = res.foreground
    if fg is None and frame is not None and tmap is not None:
        fg = foreground(frame, res.outline.mask, tmap)
    light = None
    if frame is not None:                           # the bark's albedo from the trunk's pixels
        light = scene_light(frame, res.outline.mask)
        trunk = trunk_pixels((frame.shape[0], frame.shape[1]), sk.parents, sk.nodes2d[0],
                             radius_px if radius_px is not None else radius / scale,
                             fg.mask if fg is not None else None)
        meta["bark_colour"] = (hidden_bark() if sk.hidden_trunk else bark_colour(frame, trunk, tree_px, light)).meta("albedo")
    # the pipe model's exponent and Holton's angles per fork (seed 001 §4.4), before the twigs
    meta["allometry"] = allometry_report(tree.parents, tree.nodes3d[0], tree.radius)
    tree = add_twigs(tree, s.twigs, parts["details"], tree_px)  # after the motion solve, before the leaves
    tree = add_leaves(res, tree, s, frame, tree_px, fg.mask if fg is not None else None, light)
    tree.leaves = leaves_for_form(tree, tree.leaves, res.form)    # a palm's fronds, a conifer's needle sprays
    if res.form == "palm":                      # its leaflets as wide as frame 1 shows the fronds
        tree.leaves, note = fit_fronds(tree.leaves, np.asarray(tree.meta["base_px"], float),
                                       float(tree.meta.get("metres_per_px", 1.0)), fg.mask if fg is not None else None)
        if note:
            tree.meta.update({"fronds": note})
    return tree


def grown_skeleton(sk: Skeleton2D, fill: CrownFill) -> Skeleton2D:
    """``sk`` (one frame) with a photo's grown crown (:func:`.generate.photo_crown.fill_crown`)
    appended: its nodes where frame 1 sees them, branching levels again, unmeasured."""
    n = len(fill.parents)
    xy = plane_to_image(fill.rest, sk.nodes2d[0, 0].astype(np.float64))
    conf = sk.confidence                        # (F, N): the grown nodes unmeasured in every frame
    if conf is not None:
        conf = np.concatenate([conf, np.zeros(conf.shape[:-1] + (n - conf.shape[-1],), conf.dtype)], axis=-1)
    return replace(sk, parents=fill.parents.astype(sk.parents.dtype), nodes2d=xy[None].astype(np.float32),
                   level=branching_level(fill.parents).astype(sk.level.dtype), confidence=conf)


def build_shot(results: list[Result], s: Settings | None = None, names: list[str] | None = None,
               progress: ProgressFn | None = None, photo: PhotoMotion | None = None) -> list[Tree3D]:
    """The trees of one shot (:func:`run_all`) at one scale and where they stand: the tallest in
    frame 1 is ``height_m`` tall and the others in proportion (each alone would be ``height_m``),
    and each tree's ``meta["shot_offset_m"]`` is its trunk base's place (x right, y depth 0, z up,
    metres) from the first tree's, which Blender gives its rig. One tree: :func:`build_3d`."""
    s = s or Settings()
    names = names or [f"Tree {k + 1}" for k in range(len(results))]
    if len(results) == 1:
        return [build_3d(results[0], s, names[0], progress, photo=photo)]
    tallest = max(float(np.ptp(r.skeleton.nodes2d[0, :, 1])) for r in results)
    scale = s.height_m / max(tallest, 1.0)
    n = len(results)
    trees = [build_3d(r, s, nm, sub_progress(progress, k / n, (k + 1) / n), metres_per_px=scale, photo=photo)
             for k, (r, nm) in enumerate(zip(results, names))]
    b0 = np.asarray(trees[0].meta["base_px"], float)
    for tree in trees:
        b = np.asarray(tree.meta["base_px"], float)
        tree.meta["shot_offset_m"] = [float((b[0] - b0[0]) * scale), 0.0, float((b0[1] - b[1]) * scale)]
    return trees


def first_frame(res: Result) -> np.ndarray | None:
    """Frame 1 of the run (BGR uint8, the outline's size), or None when it cannot be read again."""
    return frame_one(res.info, res.start, res.outline.mask.shape)


def add_leaves(res: Result, tree: Tree3D, s: Settings, frame: np.ndarray | None = None,
               tree_px: np.ndarray | None = None, fg: np.ndarray | None = None,
               light: SceneLight | None = None) -> Tree3D:
    """Leaf clusters from the frame-1 Harris points (``tree.leaves``, placed from the tree's
    ``meta["base_px"]`` as :func:`build_3d` records it); the tree unchanged when ``s.leaves`` is
    None or frame 1 cannot be read again. ``frame`` frame 1 if already read, ``light`` its
    :func:`.detail.albedo.scene_light` if already measured."""
    if s.leaves is None:
        return tree
    if frame is None:
        frame = first_frame(res)
    if frame is None:
        return tree
    mask = res.outline.mask
    # the paper's seeds: frame 1's Harris corners inside the outline (all of them, not only
    # those that tracked well through the clip)
    points = detect_corners(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), mask, s.track)
    # the tree's own base (the branch fit may have moved the trunk onto its centre line)
    tree.leaves = place_leaves(tree, points, frame, np.asarray(tree.meta["base_px"], float), s.leaves,
                               mask, tree_px, fg, light)
    return tree
