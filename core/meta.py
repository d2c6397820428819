"""What a :class:`~.tree3d.Tree3D`'s ``meta`` holds: one typed, documented list of keys.

``meta`` stays a plain JSON-able dict (saved inside ``tree3d.npz`` and readable by key from a
script: ``tree.meta["metres_per_px"]``); :class:`TreeMeta` types it for the checker, and
:data:`KEYS` says, per key, its unit and which stage writes it. ``tests/test_structure.py``
checks that every key a stage reads is one of these and is written by a stage, and that the
trees the pipeline and the generator make carry only these keys.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TypedDict


class EnvelopeMeta(TypedDict, total=False):
    """The crown envelope Ω in metres (:func:`.envelope.envelope_to_meta`): ``z``, ``centre``,
    ``radius`` lists of equal length; a generated tree's also the 2D ``polygon`` (metres, x/z)
    and the envelope's ``name``."""

    z: list[float]
    centre: list[float]
    radius: list[float]
    polygon: list[list[float]]
    name: str


class TreeMeta(TypedDict, total=False):
    """The keys of :attr:`.tree3d.Tree3D.meta` (see :data:`KEYS` for units and writers)."""

    # the 3D tree (pipeline.build_3d, generate.growth.grow_tree)
    height_px: float
    metres_per_px: float
    conifer: bool
    form: str
    mu_deg: float
    envelope: EnvelopeMeta
    mesh: dict[str, Any]
    # a reconstruction (pipeline.build_3d)
    limbs: str
    depth: dict[str, Any]
    motion_fit: dict[str, Any]
    photo: dict[str, Any]
    solver: str
    loop: dict[str, Any]
    periodic: dict[str, Any]
    envelope_variation: dict[str, Any]
    cuts: list[dict[str, Any]]
    tree_map: dict[str, Any]
    allometry: dict[str, Any]
    base_px: list[float]
    video_size: list[int]
    branch_fit: dict[str, Any]
    # the run that made it (cli, the Reconstruct operator)
    video: str
    frames: list[int]
    levels: int
    scale: float
    version: str
    # details (detail.twigs.add_twigs, detail.leaf_seeds.place_leaves)
    twigs: dict[str, Any]
    leaf_colour: dict[str, Any]
    fronds: dict[str, Any]
    shot_offset_m: list[float]
    bark_colour: dict[str, Any]
    # a generated tree (generate.growth.grow_tree)
    species: str
    seed: int
    generated: bool
    wind: float
    audio: str | None
    stopped: str | None
    leaf_density: float
    node_budget: int
    time_offset_s: float
    sway_scale: float
    # the file (tree3d.save_tree; kept after load_tree)
    format: str


@dataclass(frozen=True)
class Key:
    """One meta key: ``unit`` (or the shape of its value) and the stages that ``writers`` it."""

    unit: str
    writers: tuple[str, ...]
    doc: str


KEYS: dict[str, Key] = {
    "height_px": Key("px", ("pipeline.build_3d", "growth.grow_tree"),
                     "the tree's height in the lift's plane (px of the video, or of the growth raster)"),
    "metres_per_px": Key("m/px", ("pipeline.build_3d", "growth.grow_tree"),
                         "scale from the lift's plane to the scene (the tree is height_m tall)"),
    "conifer": Key("bool", ("pipeline.build_3d", "growth.grow_tree"), "the leader was kept straight in the lift"),
    "form": Key("broadleaf|conifer|palm", ("pipeline.build_3d", "growth.grow_tree"),
                "the tree's form (forms.TREE_FORMS): given, or detected from the outline"),
    "mu_deg": Key("degrees", ("pipeline.build_3d", "growth.grow_tree"), "the lift's mean branching angle μ"),
    "envelope": Key("m (EnvelopeMeta)", ("pipeline.build_3d", "growth.grow_tree"), "the crown envelope Ω"),
    "mesh": Key("{curliness 0..1, bark, seed, forks, relief_cm}", ("pipeline.build_3d", "generate.growth", "cli"),
                "the branch mesh's look, read by the Blender builder"),
    "limbs": Key("traced|grown|...", ("pipeline.build_3d",),
                 "the 2D skeleton's kind: grown where the crown's limbs were grown from a species "
                 "(asset.roles marks those nodes as grown limbs)"),
    "photo": Key("{species, seconds, wind, seed}", ("pipeline.build_3d",),
                  "a tree from one photo: the species whose sway moves it (core/generate/photo.py)"),
    "depth": Key("{source, crown_scale}", ("pipeline.build_3d",),
                  "where the lift took the depth (learned or envelope) and, learned, the crown's depth over "
                  "its width the network predicted (Ω's depth scale in the lift)"),
    "motion_fit": Key("{median, max, unmeasured, over}", ("pipeline.build_3d",),
                       "how far the 3D motion's projection lies from the measured 2D motion (shares of the "
                       "height: median, max over measured node-frames; the unmeasured share; measured "
                       "node-frames past motion.REPROJECTION_BOUND)"),
    "allometry": Key("{forks, pipe_exponent, pipe_exponent_iqr, no_exponent, leonardo_residual, holton_error_deg, "
                     "branch_angle_deg, species_mu_deg}", ("pipeline.build_3d", "growth.grow_tree"),
                     "the pipe model's exponent and Holton's branching angles measured per fork "
                     "(generate/allometry.py; before twigs)"),
    "tree_map": Key("{share, used}", ("pipeline.build_3d",),
                    "frame 1's tree pixels against the background around the outline: the share of the "
                    "outline that differs, and whether it was used (not under pipeline.MIN_TREE_SHARE)"),
    "envelope_variation": Key("{variation, weights, width_over_height, leaf_colour}", ("growth.grow_tree",),
                              "the tree's own crown and leaf colour (--envelope-variation, crown_space.py): "
                              "V, the contour space's weights, width over height source -> varied, the sRGB colour"),
    "cuts": Key("[{file, source, bones, base_node, first_node, nodes, at, placed, roll_deg, inside_share, "
                "clearance_m, taken_off, regrown}]", ("growth.grow_tree",),
                "tree-cuts placed in a generated tree (generate/cuts.py): cut k's nodes are first_node.. "
                "first_node + bones - 1, hung from base_node; at metres or where it fits"),
    "periodic": Key("{frames, seconds}", ("growth.grow_tree",),
                    "a generated tree's sway repeats after these frames (whole-period frequencies): "
                    "a loop by construction, its last frame the first"),
    "loop": Key("{frames, start, blend, seconds, whole_clip, flutter_hz, flap_hz, mismatch_deg}", ("loop.loop_tree",),
                "the seamless loop the motion was cut to (loop.py); absent: the clip as measured"),
    "solver": Key("probabilistic|deterministic", ("pipeline.build_3d",), "the 3D motion solver used"),
    "base_px": Key("[x, y] px", ("pipeline.build_3d",),
                   "the trunk base in frame 1 (after the branch fit moved the trunk onto its centre line)"),
    "video_size": Key("[w, h] px", ("pipeline.build_3d",), "frame size the reconstruction worked at"),
    "branch_fit": Key("{measured, radii, trusted, tree_share}", ("pipeline.build_3d",),
                      "what frame 1's branch widths gave (counts; tree_share of the crown 0..1)"),
    "video": Key("absolute path", ("cli",), "the video reconstructed"),
    "frames": Key("[start, stop) frames", ("cli",), "the frame range used, 0-based"),
    "levels": Key("count", ("cli",), "hierarchy levels incl. the root"),
    "scale": Key("factor (0, 1]", ("cli",), "video downscale factor"),
    "version": Key("x.y.z", ("cli", "tree3d.save_tree"),
                   "add-on version of the run (else the file format version)"),
    "twigs": Key("{first_node, nodes_added, per_generation, ...}", ("twigs.add_twigs",),
                 "twig nodes are first_node.. N-1"),
    "bark_colour": Key("{mode, colour sRGB [3], source, why}", ("pipeline.build_3d",),
                       "the bark's colour: the trunk's pixels in frame 1 as albedo, or a default bark"),
    "leaf_colour": Key("{mode, colour sRGB [3], source, why}", ("leaf_seeds.place_leaves",),
                       "the leaves' colour: the mode asked, the median colour used and how it was decided"),
    "shot_offset_m": Key("[x, y, z] metres", ("pipeline.build_shot",),
                         "where the tree's base stands from the shot's first tree (Blender places its rig there)"),
    "fronds": Key("{width_px, leaf_size_m, was_m, why}", ("pipeline.build_3d",),
                  "a palm's frond width in frame 1 and the leaflet length it gave (detail.fronds.fit_fronds)"),
    "species": Key("name", ("growth.grow_tree",), "species the tree was grown from"),
    "seed": Key("int", ("growth.grow_tree",), "growth seed"),
    "generated": Key("bool", ("growth.grow_tree",), "grown by the generator, not reconstructed"),
    "wind": Key("factor", ("growth.grow_tree",), "sway strength (1 = as in the source clip)"),
    "audio": Key("path | 'envelope' | None", ("growth.grow_tree",), "the recording whose loudness drives the sway"),
    "stopped": Key("reason | None", ("growth.grow_tree",), "why growth stopped before the node budget"),
    "leaf_density": Key("share 0..1", ("growth.grow_tree",), "share of the species' foliage grown"),
    "node_budget": Key("count", ("growth.grow_tree",), "node budget of the growth"),
    "time_offset_s": Key("s", ("growth.grow_tree",), "phase of the sway (a forest's trees differ)"),
    "sway_scale": Key("factor [0, 1]", ("growth.grow_tree",), "factor on the species' sway (at wind 1) that keeps the "
                      "swaying crown in its envelope (1: untouched)"),
    "format": Key("tree_from_video.tree3d", ("tree3d.save_tree",), "file format tag"),
}
