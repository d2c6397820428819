"""Settings saved with the .blend (``scene.tree_video``) and the running job's status
(``window_manager.tree_video_status``).

A setting the core has a parameter for takes its default and limits from the core's dataclass
(:data:`CORE_FIELDS`, via :func:`.ranges.ranged`), the motion solver's σ and bounds and the lift's
candidates too (:class:`MotionParams`, :class:`LiftParams`)."""
import bpy

from ..core.asset.game import ENGINES, GameSettings, preset
from ..core.detail.bark_photo import BarkPhotoParams
from ..core.detail.branch_mesh import MeshParams
from ..core.detail.leaf_clusters import LeafParams
from ..core.detail.relief import RELIEF_RINGS, RELIEF_SIDES
from ..core.detail.twigs import TwigParams
from ..core.formats import by_flag, interchange
from ..core.generate.batch import GenerateRequest
from ..core.generate.forest import ForestSettings
from ..core.generate.growth import GrowParams
from ..core.generate.photo import PhotoMotion
from ..core.loop import LoopSettings
from ..core.pipeline import Settings
from ..core.reconstruct.lift import LiftParams
from ..core.reconstruct.motion import MotionParams
from ..core.reconstruct.run import ReconstructSettings
from .ranges import ranged

_LIBRARY_ITEMS: list = []

#: panel property → (core dataclass, field) it mirrors: its default, its limits and (enums) its
#: choices are the core's (tests/test_defaults.py checks the registered properties against them)
CORE_FIELDS = {
    "scale": (ReconstructSettings, "scale"),
    "levels": (ReconstructSettings, "levels"),
    "skeleton_kind": (ReconstructSettings, "skeleton"),
    "form": (ReconstructSettings, "form"),
    "limbs": (Settings, "limbs"),
    "depth_source": (Settings, "depth"),
    "fold_alpha": (ReconstructSettings, "fold_alpha"),
    "solver": (MotionParams, "solver"),
    "sigma_track": (MotionParams, "sigma_track"),
    "sigma_shape": (MotionParams, "sigma_shape"),
    "max_step": (MotionParams, "max_step"),
    "max_total": (MotionParams, "max_total"),
    "candidates": (LiftParams, "candidates"),
    "height_m": (Settings, "height_m"),
    "twig_depth": (TwigParams, "depth"),
    "gen_twig_depth": (GrowParams, "twig_depth"),
    "gen_height": (GenerateRequest, "height_m"),
    "loop_seconds": (LoopSettings, "seconds"),
    "game_bones": (GameSettings, "bones"),
    "game_lods": (GameSettings, "lods"),
    "gen_nodes": (GenerateRequest, "nodes"),
    "gen_wind": (GenerateRequest, "wind"),
    "gen_envelope_variation": (GrowParams, "envelope_variation"),
    "gen_seed": (GenerateRequest, "seed"),
    "forest_variants": (ForestSettings, "variants"),
    "curliness": (MeshParams, "curliness"),
    "bark": (MeshParams, "bark"),
    "forks": (MeshParams, "forks"),
    "bark_relief": (MeshParams, "relief_cm"),
    "leaf_density": (LeafParams, "density"),
    "leaf_cards": (LeafParams, "cards"),
    "max_leaf_clusters": (LeafParams, "max_clusters"),
    "flutter_hz": (LeafParams, "flutter_hz"),
    "flutter_gain": (LeafParams, "flutter_gain"),
    "leaf_colour_mode": (LeafParams, "colour"),
    "photo_seconds": (PhotoMotion, "seconds"),
    "bark_moss": (BarkPhotoParams, "moss"),
    "bark_lichen": (BarkPhotoParams, "lichen"),
    "bark_scale": (BarkPhotoParams, "scale_cm"),
    "photo_wind": (PhotoMotion, "wind"),
}


def _core(prop: str, **kw) -> dict:
    """``default``/``min``/``max`` of panel property ``prop`` from its :data:`CORE_FIELDS` entry."""
    return ranged(*CORE_FIELDS[prop], **kw)


def _engine_text(engine: str) -> str:
    e = ENGINES[engine]
    files = [n.replace("_", " ") for n in ("pivot_painter", "bone_texture", "collision", "impostor") if e.get(n)]
    return (f"{'/'.join(e['formats']).upper()}, {e['bones']} bones, {e['lods']} LOD(s), a {e['loop_s']:g} s loop"
            + (f", {', '.join(files)}" if files else ""))


def _apply_engine(self, context):
    """Choosing an engine fills the game settings (and the loop and the export format) from its
    preset (:data:`core.asset.game.ENGINES`); the fields stay editable."""
    engine = "" if self.game_engine == "NONE" else self.game_engine.lower()
    g = preset(engine)
    self.game_bones, self.game_lods = int(g.bones), int(g.lods)
    self.game_collision, self.game_pivot_painter, self.game_bone_texture = g.collision, g.pivot_painter, g.bone_texture
    self.game_impostor = g.impostor
    self.loop_seconds = float(g.loop_s)
    if g.formats:
        self.export_format = by_flag(g.formats[0]).key


def _library_items(self, context):
    """Enum items of the bundled species (kept referenced: Blender requires it for dynamic enums)."""
    from ..core.generate.species import species_library
    _LIBRARY_ITEMS[:] = [(name, name.title(), f"Species fitted from the '{name}' sample video")
                         for name in sorted(species_library())] or [("NONE", "None", "No species bundled")]
    return _LIBRARY_ITEMS


_PHOTO_SPECIES_ITEMS: list = []


def _photo_species_items(self, context):
    """A photo's species: its traced form's own, or one of the library (kept referenced)."""
    from ..core.generate.species import species_library
    _PHOTO_SPECIES_ITEMS[:] = [("FORM", "Its Form's", "The library species of the form traced in the photo "
                                "(a conifer sways as the conifer species, a broadleaf as the broad one)")] + [
        (name, name.title(), f"Sway as the species fitted from the '{name}' sample video")
        for name in sorted(species_library())]
    return _PHOTO_SPECIES_ITEMS


def _blend_relative() -> dict:
    """Options of a path property that may start with ``//`` (Blender 4.5+ warns without the flag;
    older versions do not have it)."""
    if "is_path_supports_blend_relative" not in bpy.types.Property.bl_rna.properties:
        return {}
    return {"options": {"PATH_SUPPORTS_BLEND_RELATIVE"}}


def _holds_trees(self, coll) -> bool:
    """Export › Tree lists the collections that are a tree or hold trees (a forest)."""
    from ..operators.scene.trees import holds_trees
    return holds_trees(coll)


class TreeVideoSettings(bpy.types.PropertyGroup):
    # Source
    video_path: bpy.props.StringProperty(name="Video", subtype="FILE_PATH",
                                         description="Video of the tree moving in wind (mp4, mov, avi), or a "
                                                     "photo of it (jpg, png, tif, webp: the tree then sways as "
                                                     "a species, Source › Photo)")
    photo_species: bpy.props.EnumProperty(name="Sways As", items=_photo_species_items,
                                          description="The species whose sway a photo's tree takes (its traced "
                                                      "form's own, or one of the library)")
    photo_seconds: bpy.props.FloatProperty(name="Length", **_core("photo_seconds", open_min=0.1, soft_max=60.0),
                                           unit="TIME_ABSOLUTE",
                                           description="Seconds of sway a photo's tree is given")
    photo_wind: bpy.props.FloatProperty(name="Wind", **_core("photo_wind", soft_max=4.0),
                                        description="A photo's sway strength (1: as in the species' source "
                                                    "video, 2: twice as strong)")
    use_frame_range: bpy.props.BoolProperty(name="Frame Range", default=False,
                                            description="Use only part of the video")
    frame_start: bpy.props.IntProperty(name="Start", default=1, min=1,
                                       description="First frame of the video to use (1 = its first frame, "
                                                   "as Blender's timeline and the Movie Clip editor count)")
    frame_end: bpy.props.IntProperty(name="End", default=240, min=1,
                                     description="Last frame of the video to use (included)")
    scale: bpy.props.FloatProperty(name="Scale", subtype="FACTOR", **_core("scale", open_min=0.01, soft_min=0.05),
                                   description="Downscale the video by this factor for speed (1 = full size)")
    # Outline
    outline_source: bpy.props.EnumProperty(
        name="Outline", default="FILE",
        items=[("FILE", "File", "A polygon .json (pixels of frame 1) or a mask image (white = tree)"),
               ("MASK", "Blender Mask", "A Mask drawn over the clip in the Movie Clip editor"),
               ("AUTO", "Automatic", "What sways in the first seconds while the background stays still; in a "
                                     "photo, what stands out from the picture's border (best effort: check it "
                                     "with Track & Preview)"),
               ("ANNOTATION", "Annotation", "A closed line drawn around the tree with the Annotate tool over "
                                           "the video's clip in the Movie Clip editor, on frame 1")],
        description="Where the outline of the tree in frame 1 comes from")
    outline_path: bpy.props.StringProperty(name="Outline File", subtype="FILE_PATH",
                                           description="Polygon .json (pixels of frame 1) or mask image (white = tree)")
    outline_mask: bpy.props.PointerProperty(name="Mask", type=bpy.types.Mask,
                                            description="Mask drawn around the tree in frame 1 (Movie Clip editor)")
    # Reconstruction
    levels: bpy.props.IntProperty(name="Levels", **_core("levels"),
                                  description="Levels of the motion hierarchy, the root included: the tracked points are "
                                              "split in two by how they move, again and again (more levels: more, finer "
                                              "branches; paper: 5-7)")
    skeleton_kind: bpy.props.EnumProperty(
        name="Skeleton", **_core("skeleton_kind"),
        items=[("traced", "Traced", "Branches traced in the video, hierarchy attached through the crown"),
               ("paper", "Paper", "Cluster centroids folded toward parents (alpha = 0.4), as in the paper")],
        description="How the 2D skeleton's nodes are placed")
    fold_alpha: bpy.props.FloatProperty(name="Fold α", subtype="FACTOR", **_core("fold_alpha"),
                                        description="Paper skeleton: share of the way each node moves toward its "
                                                    "parent (x'_i += α(x'_j − x'_i); paper: 0.4)")
    form: bpy.props.EnumProperty(
        name="Form", **_core("form"),
        items=[("auto", "Auto", "Detect the form from the outline: a crown that narrows to its top is a conifer, "
                                "anything else a broadleaf (choose Palm for a palm)"),
               ("broadleaf", "Broadleaf", "A trunk forking into limbs"),
               ("conifer", "Conifer", "A central leader to the top with whorls of side branches, kept straight "
                                      "in the 3D lift"),
               ("palm", "Palm", "One trunk, curved as traced, with a crown of fronds from its top")],
        description="The tree's form: how its branches are traced and lifted, and how trees of its species grow")
    limbs: bpy.props.EnumProperty(
        name="Limbs", **_core("limbs"),
        items=[("auto", "Auto", "Traced in the video; grown from a species where no bark shows in the crown"),
               ("trace", "Trace", "Always traced in the video (where no bark shows: following how the crown moves)"),
               ("grow", "Grow", "Grown from a species inside frame 1's tree pixels: for a dense crown whose traced "
                                "limbs look like a web")],
        description="Where the crown's limbs come from; the trunk is always traced")
    limb_species: bpy.props.StringProperty(
        name="Limb Species", default="",
        description="Species grown for the limbs: a library name (broad, conifer, sparse) or a species .json file; "
                    "empty: the library species of the tree's form")
    depth_source: bpy.props.EnumProperty(
        name="Depth", **_core("depth_source"),
        items=[("envelope", "Envelope", "The outline turned about the trunk (the paper's crown envelope): branches "
                                        "spread into a round crown"),
               ("learned", "Learned", "A network trained on synthetic trees predicts from frame 1 how far each branch "
                                      "and the crown reach from the trunk's plane: flat and deep crowns too")],
        description="Where the 3D lift takes the depth a single view cannot show")
    conifer: bpy.props.BoolProperty(name="Conifer Trunk", default=False,
                                    description="Older files and presets: the same as Form › Conifer")
    candidates: bpy.props.IntProperty(name="Depth Samples", **_core("candidates"),
                                      description="Depths (toward or away from the camera) tried for each branch when "
                                                  "the 2D skeleton is lifted to 3D: more finds a rounder crown but takes "
                                                  "longer (paper: L candidates)")
    solver: bpy.props.EnumProperty(
        name="Motion Solver", **_core("solver"),
        items=[("probabilistic", "Probabilistic", "Track × shape × prior per frame, all rotations at once (paper §4)"),
               ("deterministic", "Deterministic", "Sphere about the parent joint ∩ line of sight (baseline)")],
        description="How the 3D motion is solved from the tracked 2D skeleton")
    show_advanced: bpy.props.BoolProperty(name="Advanced", default=False,
                                          description="Show the motion solver's σ and bounds")
    sigma_track: bpy.props.FloatProperty(name="Track σ", **_core("sigma_track"), precision=4,
                                         description="How far a solved branch may stray from its tracked 2D position, as "
                                                     "a share of the tree height (0.0075 = 0.75 % of it): smaller follows "
                                                     "the video more closely, larger moves more smoothly (paper: σ_track)")
    sigma_shape: bpy.props.FloatProperty(name="Shape σ", **_core("sigma_shape"), precision=3,
                                         subtype="ANGLE",
                                         description="How far the angle between a branch and its parent may drift from "
                                                     "frame 1's, at the trunk (wider toward the tips): smaller keeps the "
                                                     "branches stiffer (paper: σ_shape)")
    max_step: bpy.props.FloatProperty(name="Max Step", **_core("max_step"), subtype="ANGLE",
                                      description="Largest turn of a branch from one frame to the next (per axis)")
    max_total: bpy.props.FloatProperty(name="Max Total (Δ)", **_core("max_total"), subtype="ANGLE",
                                       description="Largest total turn of a branch away from its frame-1 pose "
                                                   "(paper: Δ)")
    # Output
    height_m: bpy.props.FloatProperty(name="Tree Height", unit="LENGTH",
                                      **_core("height_m", open_min=0.1, soft_max=200.0),
                                      description="Height of the reconstructed tree in the scene (metres)")
    loop_seconds: bpy.props.FloatProperty(name="Loop (s)", **_core("loop_seconds", soft_max=60.0),
                                          description="Cut the new tree's animation to a seamless loop of this many "
                                                      "seconds for game engines (0: the clip as measured; longer "
                                                      "than the clip: the whole clip, its seam blended); its action "
                                                      "and every export's animation are named <tree>_loop")
    build_mesh: bpy.props.BoolProperty(name="Branch Mesh", default=True,
                                       description="Build skinned bark tubes along the bones")
    fit_branches: bpy.props.BoolProperty(name="Fit to Video", default=True,
                                         description="Measure branch widths and centre lines in the first frame "
                                                     "(the trunk sets the scale of all radii); off: pipe-model radii")
    twig_depth: bpy.props.IntProperty(name="Twig Depth", **_core("twig_depth"),
                                      description="Generations of twigs grown from every branch tip by copying the "
                                                  "tree's own forks (0: none); they ride on their branch's motion")
    curliness: bpy.props.FloatProperty(name="Curliness", subtype="FACTOR", **_core("curliness"),
                                       description="Bend the branch tubes along minimum-jerk curves (0: straight; "
                                                   "1: up to 12% of each bone's length)")
    bark: bpy.props.EnumProperty(
        name="Bark", **_core("bark"),
        items=[("none", "None", "Round tubes"),
               ("smooth", "Smooth", "Bark relief up to 0.5% of the radius (beech, birch)"),
               ("rough", "Rough", "Bark relief of 1-5% of the radius (oak, pine)")],
        description="Relief of the bark around the branch tubes")
    forks: bpy.props.EnumProperty(
        name="Forks", **_core("forks"),
        items=[("joined", "Joined", "Where branches fork the tubes join into one closed surface; the "
                                    "continuing branch starts at the pipe model's radius"),
               ("overlap", "Overlap", "Each branch is its own tube, starting inside its parent")],
        description="How the branch tubes meet where the tree forks")
    bark_relief: bpy.props.FloatProperty(name="Relief (cm)", **_core("bark_relief"),
                                         description="The bark's height map (the photo's, or the procedural "
                                                     "bark's) as geometry on the tubes: its depth on the trunk, "
                                                     "thinner on thinner branches; in every export's first level "
                                                     f"(0: none; the tubes get at least {RELIEF_SIDES} sides and "
                                                     f"{RELIEF_RINGS} rings)")
    bark_image: bpy.props.StringProperty(name="Bark Image", subtype="FILE_PATH", **_blend_relative(),
                                         description="A close-up photo of the bark, or a folder of them: the bark "
                                                     "becomes a seamless tile quilted from it (colour, relief, "
                                                     "roughness) instead of the procedural one, in every export; "
                                                     "photos of the same bark a step apart give its relief by "
                                                     "parallax (empty: procedural)")
    bark_moss: bpy.props.FloatProperty(name="Moss", **_core("bark_moss"), subtype="FACTOR",
                                       description="Moss found in the bark photo (green): 0 removes it, 1 as "
                                                   "photographed, 2 doubles its cover, crevices first")
    bark_lichen: bpy.props.FloatProperty(name="Lichen", **_core("bark_lichen"), subtype="FACTOR",
                                         description="Lichen found in the bark photo (pale grey, bright yellow): "
                                                     "0 removes it, 1 as photographed, 2 doubles its cover")
    bark_scale: bpy.props.FloatProperty(name="Bark Scale (cm)", **_core("bark_scale", open_min=1.0, soft_max=300.0),
                                        description="How much bark one tile of the photo's bark shows on the tree, cm")
    build_leaves: bpy.props.BoolProperty(name="Leaves", default=True,
                                         description="Leaf clusters where the video shows foliage (seeds: Harris corners "
                                                     "of frame 1), riding their branches with their own flutter")
    leaf_density: bpy.props.FloatProperty(name="Leaf Density", subtype="FACTOR",
                                          **_core("leaf_density", open_min=0.01, soft_min=0.02),
                                          description="Share of the leaf seeds kept: fewer, larger clusters and fewer "
                                                      "polygons (polygons = clusters × cards)")
    leaf_cards: bpy.props.IntProperty(name="Leaf Cards", **_core("leaf_cards", soft_max=128),
                                      description="Leaves per cluster: leaf cards, one quad each")
    max_leaf_clusters: bpy.props.IntProperty(name="Max Clusters", **_core("max_leaf_clusters"),
                                             description="Upper bound on leaf clusters (each is one bone)")
    flutter_hz: bpy.props.FloatProperty(name="Flutter", unit="NONE", **_core("flutter_hz", soft_max=12.0),
                                        description="Leaf flutter frequency ω/2π in Hz (kept below half the frame rate)")
    flutter_gain: bpy.props.FloatProperty(name="Flutter Amount", **_core("flutter_gain", soft_max=50.0),
                                          description="How strongly the leaves flutter as their branch moves, in seconds: "
                                                      "the flutter angle A = amount × branch speed / tree height "
                                                      "(radians)")
    leaf_colour_mode: bpy.props.EnumProperty(
        name="Leaf Colour", **_core("leaf_colour_mode"),
        items=[("albedo", "Albedo", "The video's foliage colour corrected for the scene's exposure and white "
                                    "balance; a plausible foliage green where the video shows a dark, backlit or "
                                    "grey silhouette"),
               ("video", "Video", "The colour the video shows, as sampled (a backlit crown comes out dark)"),
               ("custom", "Custom", "Your colour, each cluster a little lighter or darker as in the video")],
        description="Colour of the leaves")
    leaf_colour_custom: bpy.props.FloatVectorProperty(
        name="Custom Colour", subtype="COLOR_GAMMA", size=3, min=0.0, max=1.0, default=(0.33, 0.46, 0.18),
        description="The leaves' colour when Leaf Colour is Custom")
    leaf_image: bpy.props.StringProperty(name="Leaf Image", subtype="FILE_PATH",
                                         description="Image of one leaf (alpha = shape, stem at the bottom); empty: "
                                                     "a procedural leaf")
    leaf_polygons: bpy.props.IntProperty(name="Leaf Polygons", default=0, min=0,
                                         description="Leaf polygons of the last tree built (read only)")
    motion_measured: bpy.props.FloatProperty(name="Motion Measured", default=-1.0, min=-1.0, max=1.0,
                                             description="Share of node-frames whose motion the last reconstruction "
                                                         "or preview measured (confidence >= 0.5; -1: none yet; "
                                                         "read only)")
    collection_name: bpy.props.StringProperty(name="Collection", default="Tree from Video",
                                              description="Collection that holds the tree's armature and mesh")
    replace_existing: bpy.props.BoolProperty(name="Replace Existing", default=False,
                                             description="Replace a collection of the same name (else refuse)")
    # Generate (paper §5)
    species_source: bpy.props.EnumProperty(
        name="Species", default="LIBRARY",
        items=[("LIBRARY", "Library", "A species shipped with the add-on (fitted from the sample videos)"),
               ("FILE", "File", "A species .json (Save Species writes one from a reconstruction)"),
               ("RECONSTRUCTION", "Reconstructed Tree", "Fit the species to a tree reconstructed in this file: the "
                "selected one (click its rig or mesh), or the only one")],
        description="Where the species model (bifurcation and motion statistics) comes from")
    species_name: bpy.props.EnumProperty(name="Library Species", items=_library_items,
                                         description="Species fitted from the bundled sample videos")
    species_path: bpy.props.StringProperty(name="Species File", subtype="FILE_PATH",
                                           description="Species model .json (human-readable; shareable)")
    envelope_source: bpy.props.EnumProperty(
        name="Envelope", default="CIRCLE",
        items=[("SOURCE", "Source Outline", "The crown envelope of a reconstructed tree: the one the species is "
                "fitted to, else the selected one (or the file's only one)"),
               ("CIRCLE", "Circle", "Topiary: a round crown on a stem"),
               ("TRIANGLE", "Triangle", "Topiary: a cone"),
               ("PENTAGON", "Pentagon", "Topiary: a pentagon"),
               ("HEART", "Heart", "Topiary: a heart"),
               ("IMAGE", "Image", "Any silhouette image (dark or opaque shape)"),
               ("CURVE", "Curve", "A closed curve object drawn in the front (X/Z) view")],
        description="The shape new trees grow into (a surface of revolution of this outline)")
    envelope_image: bpy.props.StringProperty(name="Silhouette", subtype="FILE_PATH",
                                             description="Image whose dark or opaque pixels are the crown's shape")
    envelope_curve: bpy.props.PointerProperty(name="Curve", type=bpy.types.Object,
                                              poll=lambda self, ob: ob.type == "CURVE",
                                              description="Closed curve in the X/Z plane, trunk base at its lowest point")
    gen_seed: bpy.props.IntProperty(name="Seed", **_core("gen_seed"),
                                    description="Random seed: the same seed grows the same tree")
    gen_height: bpy.props.FloatProperty(name="Height", **_core("gen_height", open_min=0.1, soft_max=200.0),
                                        unit="LENGTH", description="Height of a generated tree (metres)")
    gen_nodes: bpy.props.IntProperty(name="Nodes", **_core("gen_nodes", soft_max=5000),
                                     description="Node budget of a generated tree (bones + 1)")
    gen_twig_depth: bpy.props.IntProperty(name="Twigs", **_core("gen_twig_depth"),
                                          description="Generations of twigs copied from a generated tree's own forks "
                                                      "onto its branch tips, riding on their motion (0: none); the "
                                                      "foliage hangs on them, as on a reconstruction's")
    gen_leaf_density: bpy.props.FloatProperty(name="Foliage", default=1.0, min=0.0, max=1.0, subtype="FACTOR",
                                              description="Share of the species' leaf clusters on a generated tree (1: as "
                                                          "leafy as the species, fewer: fewer, larger clusters; 0: bare)")
    gen_envelope_variation: bpy.props.FloatProperty(
        name="Crown Variety", **_core("gen_envelope_variation"), subtype="FACTOR",
        description="Each generated tree grows in its own crown around the envelope: its outline mixed this far "
                    "toward the species' and the library's crown outlines (seed 000's contour space), its leaf "
                    "colour likewise within the species' range (0: the envelope as given)")
    gen_allometry: bpy.props.BoolProperty(
        name="Holton Angles", default=False,
        description="Turn each fork's two children together so the thicker bends less, by Holton's rule "
                    "(seed 001's allometry), within the envelope; broadleaf trees (it moves the species' "
                    "measured split of the fork angle)")
    gen_cut: bpy.props.StringProperty(
        name="Cut", subtype="FILE_PATH",
        description="A tree-cut (.npz from Save Cut) that generated trees must contain: Generate places it where "
                    "its base's radius fits, Place Cut on the selected generated tree where the 3D cursor is; the "
                    "tree's branches in its way grow elsewhere")
    gen_wind: bpy.props.FloatProperty(name="Wind", **_core("gen_wind", soft_max=10.0),
                                      description="Sway amplitude relative to the source video (2 = twice as strong)")
    gen_audio: bpy.props.StringProperty(name="Wind Audio", subtype="FILE_PATH",
                                        description="Optional .wav whose loudness drives the sway (e.g. a windy day)")
    gen_frames: bpy.props.IntProperty(name="Frames", default=0, min=0, max=100000,
                                      description="Length of the generated animation in frames (0: the scene's "
                                                  "frame range when it holds a tree, else the source clip's)")
    forest_name: bpy.props.StringProperty(name="Forest", default="Forest",
                                          description="Collection that holds the forest's trees")
    forest_count: bpy.props.IntProperty(name="Trees", default=12, min=1, max=1000,
                                        description="Number of trees in the forest")
    forest_variants: bpy.props.IntProperty(name="Variants", **_core("forest_variants", soft_max=50),
                                           description="Distinct trees the forest grows; each stands several times, "
                                                       "turned, sized and out of step, sharing its mesh and motion "
                                                       "(a smaller .blend). 0: every tree its own. A Wind Audio "
                                                       "forest grows every tree on its own")
    forest_spacing: bpy.props.FloatProperty(name="Spacing", default=6.0, min=0.1, max=1000.0, unit="LENGTH",
                                            description="Smallest distance between two trees (Poisson-disk)")
    forest_ground: bpy.props.PointerProperty(name="Ground", type=bpy.types.Object,
                                             poll=lambda self, ob: ob.type == "MESH",
                                             description="Mesh to scatter the trees on (empty: an area at the 3D cursor)")
    forest_width: bpy.props.FloatProperty(name="Area Width", default=40.0, min=0.1, unit="LENGTH",
                                          description="Area along X when no ground mesh is chosen (metres)")
    forest_depth: bpy.props.FloatProperty(name="Area Depth", default=40.0, min=0.1, unit="LENGTH",
                                          description="Area along Y when no ground mesh is chosen (metres)")
    # Export
    export_scope: bpy.props.EnumProperty(
        name="Export", default="SELECTED",
        items=[("SELECTED", "Selected Trees", "The trees of the selected objects (else the active object's, the active "
                "collection's or the file's only tree), each to its own file named after it"),
               ("PICK", "Pick a Tree", "The tree or forest picked from the file's trees (a forest: each tree to its own "
                "file)")],
        description="Which trees to export")
    export_tree: bpy.props.PointerProperty(name="Tree", type=bpy.types.Collection, poll=_holds_trees,
                                           description="Tree or forest of this file to export (a reconstruction, "
                                                       "a generated tree, a forest)")
    export_name: bpy.props.StringProperty(name="File Name",
                                          description="Name of the file, without extension (empty: the tree's name); "
                                                      "several trees are each named after their tree")
    output_dir: bpy.props.StringProperty(name="Folder", subtype="DIR_PATH", default="//tree_from_video",
                                         description="Folder for exported files (// = beside the saved .blend file)",
                                         **_blend_relative())
    overwrite: bpy.props.BoolProperty(name="Overwrite", default=False,
                                      description="Replace existing files in the output folder")
    # the game export (issue 33): applied when a tree is built (Reconstruct, Generate, Forest); the
    # engine files are kept with the tree and written beside it by Export
    game_engine: bpy.props.EnumProperty(
        name="Engine", default="NONE", update=_apply_engine,
        items=[("NONE", "Film (no preset)", "Every bone, the film meshes, no engine files")]
        + [(k.upper(), k.capitalize() if k != "web" else "Web (three.js)", _engine_text(k)) for k in sorted(ENGINES)],
        description="A game engine's preset: fills Bones, LODs, Loop and the engine files below")
    game_bones: bpy.props.IntProperty(name="Bones", **_core("game_bones", soft_max=256),
                                      description="The most bones a new tree's rig keeps (0: every bone); the motion "
                                                  "is re-fitted and the vertex error reported")
    game_lods: bpy.props.IntProperty(name="LODs", **_core("game_lods"),
                                     description="Levels of detail <tree>_LOD0.. (about 100 %, 40 %, 15 % of LOD0's "
                                                 "triangles) on the same rig; 1: the film meshes")
    game_collision: bpy.props.BoolProperty(name="Collision Capsules", default=False,
                                           description="Capsules UCP_<tree>_NN for the trunk and main limbs (in the FBX) "
                                                       "and collision.json")
    game_pivot_painter: bpy.props.BoolProperty(name="Pivot Painter 2", default=False,
                                               description="Unreal Pivot Painter 2 textures (element per branch in UV "
                                                           "channel 1) and the measured wind per level")
    game_impostor: bpy.props.BoolProperty(name="Impostor", default=False,
                                          description="A hemi-octahedral atlas of the tree (8x8 views, albedo and "
                                                      "normals) and a crossed-billboard card as the last LOD")
    game_bone_texture: bpy.props.BoolProperty(name="Bone Texture", default=False,
                                              description="The motion as a bone-animation texture (EXR + JSON) for "
                                                          "vertex-shader skinning")
    export_format: bpy.props.EnumProperty(
        name="Format", default="FBX",
        items=[(f.key, f.label, f.description) for f in interchange()],
        description="File format of the export")


classes = (TreeVideoSettings,)


def register():
    for c in classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.tree_video = bpy.props.PointerProperty(type=TreeVideoSettings)
    bpy.types.WindowManager.tree_video_status = bpy.props.StringProperty(
        name="Status", description="What the running reconstruction is doing")
    bpy.types.WindowManager.tree_video_progress = bpy.props.FloatProperty(
        name="Progress", subtype="PERCENTAGE", min=0, max=100, description="Progress of the running reconstruction")


def unregister():
    del bpy.types.WindowManager.tree_video_progress
    del bpy.types.WindowManager.tree_video_status
    del bpy.types.Scene.tree_video
    for c in reversed(classes):
        bpy.utils.unregister_class(c)
