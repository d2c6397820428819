"""Reconstruct: video + outline → animated tree in the scene, without freezing Blender.

The core runs in a worker thread (:class:`core.job.Job`, it touches no bpy); a modal operator polls
it on a timer, shows progress in the status bar and the panel, and Esc cancels within a second.
The scene is only touched at the end, on the main thread, inside this operator's single undo
step: a cancelled or failed run leaves the scene exactly as it was.
"""
from __future__ import annotations

import os

import bpy
import numpy as np

from ..core import jobs as jobs_core
from ..core import pipeline
from ..core.errors import InputError
from ..core.generate.batch import load_species_spec
from ..core.generate.photo import PhotoMotion, check_photo, is_photo
from ..core.job import Job
from ..core.loop import maybe_loop
from ..core.reconstruct.node_motion import confidence_summary, low_share
from ..core.reconstruct.video import open_video
from . import jobs
from .scene import annotation, clip_overlay, clip_view, provenance, stored
from .scene.bark_photos import panel_bark
from .scene.build import build_tree
from .scene.checks import missing_file, refuse
from .scene.game import build_kwargs, game_settings, keep_engine_files


def cache_dir() -> str:
    """Where tracks and hierarchies are cached: the extension's user folder when installed as an
    extension (Blender 4.2+), else a folder in the system's temp directory."""
    package = __package__.rsplit(".", 1)[0]
    if package.startswith("bl_ext.") and hasattr(bpy.utils, "extension_path_user"):
        try:
            return bpy.utils.extension_path_user(package, path="cache", create=True)
        except (ValueError, OSError):
            pass
    import tempfile
    return os.path.join(tempfile.gettempdir(), "tree_from_video_cache")


def panel_options(props) -> dict:
    """The panel's reconstruction settings by the batch options' names (:data:`core.jobs.OPTIONS`):
    what :func:`core.jobs.from_flat` builds the panel's job from, as it does the command line's."""
    spec = props.limb_species.strip()
    flat = dict(levels=props.levels, skeleton=props.skeleton_kind, fold_alpha=props.fold_alpha, scale=props.scale,
                frames=frame_range(props) if props.use_frame_range else None, height=props.height_m,
                form=props.form, conifer=props.conifer, limbs=props.limbs,
                limb_species=bpy.path.abspath(spec) if spec.lower().endswith(".json") else spec,
                candidates=props.candidates, solver=props.solver, sigma_track=props.sigma_track,
                sigma_shape=props.sigma_shape, max_step=props.max_step, max_total=props.max_total,
                twigs=props.twig_depth, no_branch_fit=not props.fit_branches, curliness=props.curliness,
                bark=props.bark, forks=props.forks, bark_relief=props.bark_relief,
                no_leaves=not props.build_leaves, depth=props.depth_source)
    if props.build_leaves:
        flat.update(leaf_density=props.leaf_density, leaf_cards=props.leaf_cards,
                    max_leaf_clusters=props.max_leaf_clusters, flutter_hz=props.flutter_hz,
                    flutter_gain=props.flutter_gain,
                    leaf_colour=leaf_colour_setting(props.leaf_colour_mode, props.leaf_colour_custom))
    return flat


def settings_from(props) -> pipeline.Settings:
    """Core settings from the panel's properties, as the batch reads its options
    (:func:`core.jobs.settings_of`); tracking is cached per video and settings."""
    s = jobs_core.settings_of(jobs_core.check_types(panel_options(props), "the panel"))
    s.cache_dir = cache_dir()
    return s


#: the outline of a panel job whose outline is drawn in Blender (a Mask, an annotation): no file
DRAWN = "drawn in Blender"


def panel_job(props, video: str, outline):
    """The panel's run as a typed job (:func:`core.jobs.from_flat`, the command line's reader): a
    :class:`~core.jobs.ReconstructJob`, or a :class:`~core.jobs.PhotoJob` with Source › Photo's
    species, length and wind; ``outline`` a file's path, "auto" or a drawn polygon (named
    :data:`DRAWN`); no output folder (the tree is built in the scene)."""
    flat = {**panel_options(props), "video": video, "outline": outline if isinstance(outline, str) else DRAWN}
    if is_photo(video):
        flat.update(species=None if props.photo_species == "FORM" else props.photo_species,
                    seconds=float(props.photo_seconds), wind=float(props.photo_wind))
    job = jobs_core.from_flat(flat, "the panel")
    job.settings.cache_dir = cache_dir()
    return job


def frame_range(props) -> str:
    """The core's 0-based, end-exclusive ``"A:B"`` of the panel's Frame Range, which counts as
    Blender's timeline does: from 1, both ends included (Start 1, End 24: the video's first 24)."""
    return f"{max(props.frame_start, 1) - 1}:{props.frame_end}"


def leaf_colour_setting(mode: str, custom) -> str:
    """``LeafParams.colour`` from the panel: its mode, or the custom colour (sRGB 0..1) as ``#RRGGBB``."""
    if mode != "custom":
        return mode
    r, g, b = (int(round(255 * min(max(float(c), 0.0), 1.0))) for c in custom)
    return f"#{r:02X}{g:02X}{b:02X}"


def mask_polygon(mask, width: int, height: int) -> np.ndarray:
    """Pixel polygon ``(M, 2)`` of the first spline of ``mask`` (a Blender Mask drawn on the clip;
    its coordinates are normalized to the frame, y up)."""
    for layer in mask.layers:
        for spline in layer.splines:
            co = np.array([p.co[:] for p in spline.points], float).reshape(-1, 2)
            if len(co) >= 3:
                return np.stack([co[:, 0] * width, (1.0 - co[:, 1]) * height], axis=1)
    raise InputError(f"mask '{mask.name}' has no closed spline with 3 or more points; "
                     "draw the outline around the tree in the Movie Clip editor's Mask mode")


def inputs_from(props):
    """(video path, outline: path or pixel polygon), checked enough to fail fast on the main thread."""
    video = bpy.path.abspath(props.video_path)
    if not props.video_path:
        raise InputError("no video chosen; pick the video file in the Source panel")
    if is_photo(video):
        check_photo(video)                 # a photo: one clear line for a tiny, flat or unreadable one
    info = open_video(video)               # raises a clear InputError for missing/unreadable files
    if props.outline_source == "AUTO":
        return video, "auto"
    if props.outline_source == "ANNOTATION":        # one tree per closed stroke
        polys = annotation.video_annotation_polygons(video, int(info.width), int(info.height))
        return video, (polys[0] if len(polys) == 1 else polys)
    if props.outline_source == "MASK":
        if props.outline_mask is None:
            raise InputError("no outline mask chosen; draw a Mask around the tree and pick it in the Outline panel")
        return video, mask_polygon(props.outline_mask, int(info.width), int(info.height))
    if not props.outline_path:
        raise InputError("no outline drawn; pick a polygon .json or a mask image in the Outline panel")
    return video, bpy.path.abspath(props.outline_path)


def why_not(props) -> str | None:
    """Why Reconstruct and Track & Preview are disabled (their poll message), or None: a job is
    running, no video or no outline (or one that does not exist). Cheap: file checks are cached."""
    if props is None:
        return "the add-on's settings are missing; enable Tree from Video again"
    if jobs.running():
        return "a job is running; wait for it to finish or press Cancel"
    problem = missing_file(props.video_path, "video", "Source")
    if problem:
        return problem
    if props.outline_source == "FILE":
        return missing_file(props.outline_path, "outline file", "Outline")
    if props.outline_source == "MASK" and props.outline_mask is None:
        return ("no outline mask chosen; press Open Clip to Draw Outline, draw a Mask around the tree "
                "on frame 1 and pick it in the Outline panel")
    if props.outline_source == "ANNOTATION":
        ok, text = annotation.status(props.video_path)
        if not ok:
            return f"no outline yet ({text}); press Open Clip to Draw Outline and draw around the tree on frame 1"
    return None


def tree_names(name: str, n: int) -> list[str]:
    """The collection of each of ``n`` trees one outline holds: ``name``, or ``name 1``, ``name 2``…
    (a file of several polygons, a mask of several components, several closed annotation strokes)."""
    return [name] if n == 1 else [f"{name} {k + 1}" for k in range(n)]


def make_work(video, outline, settings: pipeline.Settings, name: str, record=None, photo=None):
    """The worker's function: skeleton, lift and motion (pure core, no bpy) of every tree the
    outline holds: ``[(Result, Tree3D), ...]`` named by :func:`tree_names`; a photo's tree sways as
    ``photo`` says (:class:`core.generate.photo.PhotoMotion`; None: its defaults). ``record`` (a
    :class:`core.farm.report.JobRecord`, :mod:`.scene.provenance`) gets the input's identity, the
    seconds per stage, the video read, the counts and the warnings."""
    from ..core.progress import sub_progress

    def work(progress):
        if record is not None:
            provenance.set_input(record, video, outline)
            progress = record.timed(progress)
        # the 2D stages get their share of the expected time (pipeline.STAGE_COSTS_2D and _3D: ≈ 72 %
        # at 180 frames, 76 % at 555, since the motion solve is one sparse solve a frame), so the bar
        # moves evenly
        split = pipeline.share_2d(pipeline.clip_frames(video, settings))
        results = pipeline.run_all(video, outline, settings, sub_progress(progress, 0.0, split))
        motion = (photo or PhotoMotion()) if is_photo(video) else None      # a photo sways as a species
        trees = pipeline.build_shot(results, settings, tree_names(name, len(results)),
                                    sub_progress(progress, split, 1.0), photo=motion)   # one scale, each where it stands
        pairs = list(zip(results, trees))
        if record is not None:
            provenance.record_results(record, pairs)
        return pairs
    return work


class TREE_OT_reconstruct(jobs.JobOperator, bpy.types.Operator):
    """Reconstruct the animated tree from the video and outline (Esc cancels)"""

    bl_idname = "tree_video.reconstruct"
    bl_label = "Reconstruct"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        why = why_not(getattr(context.scene, "tree_video", None))
        return refuse(cls, why) if why else True

    def make_job(self, context) -> Job:
        props = context.scene.tree_video
        video, outline = inputs_from(props)
        name = props.collection_name.strip() or "Tree from Video"
        # "auto" finds its trees in the worker (seconds of video); a file or a drawing is counted now
        n = 1 if isinstance(outline, str) and outline == "auto" else pipeline.count_outlines(video, outline)
        for each in tree_names(name, n):
            if bpy.data.collections.get(each) is not None and not props.replace_existing:
                raise InputError(f"a collection named '{each}' exists; tick Replace Existing or change the name")
        panel_bark(props)                                   # a bad bark photo: one line before any work
        if props.build_leaves and props.leaf_image and not os.path.isfile(bpy.path.abspath(props.leaf_image)):
            raise InputError(f"leaf image '{props.leaf_image}' does not exist; pick an image file or clear the field "
                             "for the procedural leaf")
        job = panel_job(props, video, outline)
        photo = job.motion if isinstance(job, jobs_core.PhotoJob) else None
        if photo is not None and photo.species:
            load_species_spec(photo.species)            # a missing or broken species file fails now
        self._record = provenance.panel_record(jobs_core.settings_doc(job), video)
        return Job(make_work(video, outline, job.settings, name, self._record, photo))

    def done(self, context, result):
        props = context.scene.tree_video
        taken = [t.name for _, t in result if bpy.data.collections.get(t.name) is not None]
        if taken and not props.replace_existing:        # "auto" found more trees than were counted
            self.report({"ERROR"}, f"a collection named '{taken[0]}' exists; tick Replace Existing or change the name")
            return {"CANCELLED"}
        built = []
        for res, tree in result:
            one = self._build(context, props, res, tree)
            if one is None:
                return {"CANCELLED"}
            built.append(one)
        record = getattr(self, "_record", None)
        if record is not None:                          # the run's report, kept with each tree it built
            record.add(bones=sum(len(b["armature"].data.bones) for b in built))
            record.finish("ok", None, None)
            for b in built:
                provenance.keep(b["collection"], record)
        return {"FINISHED"}

    def _build(self, context, props, res, tree):
        """One reconstructed tree into its collection; None (reported) when it cannot be built."""
        try:
            tree, note = maybe_loop(tree, props.loop_seconds)
            if note:
                self.report({"INFO"}, note)
            game = game_settings(props)
            built = build_tree(context, tree, tree.name, replace=props.replace_existing, mesh=props.build_mesh,
                               leaf_image=bpy.path.abspath(props.leaf_image) if props.leaf_image else None,
                               bark_maps=panel_bark(props), **build_kwargs(game))
            keep_engine_files(built, tree, game)
        except InputError as exc:
            self.report({"ERROR"}, str(exc))
            return None
        stored.store_tree(built["collection"], tree, res.info.path)     # Save Species, Generate: any tree, any time
        clip_overlay.store(res, built["collection"])
        props.leaf_polygons = built["leaf_polygons"]
        photo = is_photo(res.info.path)                 # its motion is the species', not measured
        props.motion_measured = -1.0 if photo else measured_share(res)
        for w in pipeline.tree_warnings(res, tree):
            self.report({"WARNING"}, w)
        leaves = f", {built['leaf_polygons']:,} leaf polygons" if built["leaf_polygons"] else ""
        self.report({"INFO"}, f"{len(built['armature'].data.bones)} bones × {tree.n_frames} frames in "
                              f"'{tree.name}'{leaves}; {'swaying as its species' if photo else motion_summary(res)}")
        return built


def motion_summary(res) -> str:
    """The report's line on how well the motion was measured (empty when it was not)."""
    conf = res.skeleton.confidence
    return "" if conf is None else confidence_summary(conf)


def measured_share(res) -> float:
    """Share of node-frames measured (the panel's line), -1 when the motion was not measured."""
    conf = res.skeleton.confidence
    return -1.0 if conf is None else 1.0 - low_share(conf)


class TREE_OT_preview(jobs.JobOperator, bpy.types.Operator):
    """Track the video and build the 2D skeleton only, then open the clip in the Movie Clip editor
    with the tracks and skeleton drawn over it (nothing is added to the scene)"""

    bl_idname = "tree_video.preview"
    bl_label = "Track & Preview"
    bl_options = {"REGISTER"}
    what = "tracking preview"

    @classmethod
    def poll(cls, context):
        why = why_not(getattr(context.scene, "tree_video", None))
        return refuse(cls, why) if why else True

    def make_job(self, context) -> Job:
        video, outline = inputs_from(context.scene.tree_video)
        settings = settings_from(context.scene.tree_video)
        return Job(lambda progress: pipeline.run(video, outline, settings, progress))

    def done(self, context, result):
        clip = clip_view.clip_for(os.path.abspath(result.info.path))
        clip_overlay.store(result, context.scene)        # kept in the file: drawn again after reopening
        context.scene.tree_video.motion_measured = measured_share(result)
        area = clip_view.show_clip(context, clip, result.start + 1)
        for w in result.warnings:
            self.report({"WARNING"}, w)
        where = "in the Movie Clip editor" if area is not None else f"over clip '{clip.name}' in the Movie Clip editor"
        self.report({"INFO"}, f"{result.tracks.n_tracks} tracks, {result.skeleton.n_nodes} nodes {where}; "
                              f"{motion_summary(result)}")
        jobs.redraw(context, "CLIP_EDITOR")
        return {"FINISHED"}


class TREE_OT_cancel(bpy.types.Operator):
    """Stop the running reconstruction (the scene stays as it was)"""

    bl_idname = "tree_video.cancel"
    bl_label = "Cancel"

    @classmethod
    def poll(cls, context):
        return jobs.running() or refuse(cls, "nothing is running")

    def execute(self, context):
        jobs.request_cancel(context)
        return {"FINISHED"}


class TREE_OT_open_clip(bpy.types.Operator):
    """Open the video in a Movie Clip editor to draw the outline on frame 1: as a Mask, or with the
    Annotate tool when the outline source is Annotation"""

    bl_idname = "tree_video.open_clip"
    bl_label = "Open Clip to Draw Outline"

    @classmethod
    def poll(cls, context):
        props = getattr(context.scene, "tree_video", None)
        if props is None:
            return refuse(cls, "the add-on's settings are missing; enable Tree from Video again")
        why = missing_file(props.video_path, "video", "Source")
        return refuse(cls, why) if why else True

    def execute(self, context):
        path = bpy.path.abspath(context.scene.tree_video.video_path)
        if not os.path.isfile(path):
            self.report({"ERROR"}, f"video '{path}' does not exist; check the path in the Source panel")
            return {"CANCELLED"}
        clip = annotation.clip_for_video(path) or bpy.data.movieclips.load(path)
        area = next((a for a in context.screen.areas if a.type == "CLIP_EDITOR"), None) if context.screen else None
        if area is None and context.area is not None:
            area = context.area
            area.type = "CLIP_EDITOR"
        if area is not None:
            space = area.spaces.active
            space.clip = clip
            if context.scene.tree_video.outline_source == "ANNOTATION":
                space.mode = "TRACKING"
                annotation.show_annotation_tools(area)
            else:
                space.mode = "MASK"
                if space.mask is None:
                    space.mask = bpy.data.masks.new(f"{clip.name} outline")
                context.scene.tree_video.outline_source = "MASK"
                context.scene.tree_video.outline_mask = space.mask
        context.scene.frame_set(1)
        return {"FINISHED"}


classes = (TREE_OT_reconstruct, TREE_OT_preview, TREE_OT_cancel, TREE_OT_open_clip)

_register, _unregister = bpy.utils.register_classes_factory(classes)


def register():
    _register()
    clip_overlay.register()


def unregister():
    jobs.cancel_all()
    clip_overlay.unregister()
    _unregister()
