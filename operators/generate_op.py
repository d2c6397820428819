"""Generate new animated trees of a species (paper §5) in the scene: one tree at the 3D cursor, or a
forest scattered on a ground mesh or an area, each a distinct sample with its own phase.

Growing runs in a worker thread (like Reconstruct: progress, Esc cancels); a forest is then built
a few trees per timer tick so Blender stays responsive, and Esc during building removes the trees
built so far. All trees of a forest share one bark and one leaf material.
"""
from __future__ import annotations

import math
import os

import bpy
import numpy as np

from ..core.envelope import envelope_from_meta
from ..core.errors import InputError
from ..core.generate import envelopes, forest, growth, species
from ..core.generate.cuts import CutSpec
from ..core.generate.regrow import inputs_doc
from ..core.job import Job
from ..core.loop import maybe_loop
from ..core.progress import sub_progress
from . import jobs
from .scene import stored, timing, trees
from .scene.bark_photos import species_bark
from .scene.build import build_tree
from .scene.checks import missing_file, refuse
from .scene.forest import ForestBuild
from .scene.game import build_kwargs, game_settings, keep_engine_files
from .scene.objects import evaluated_world_mesh, unique_collection_name

#: seconds of building per timer tick while a forest is built
BUILD_SLICE_S = 0.15


# ----------------------------------------------------------------------------- inputs

def species_from(props, context=None):
    """``(model or None, tree or None)``: the species to grow. A library or file species is loaded
    here (fast); for a reconstructed tree (the selected one, see :func:`.scene.stored.selected`)
    the tree is returned and fitted in the worker."""
    src = props.species_source
    if src == "LIBRARY":
        lib = species.species_library()
        if props.species_name not in lib:
            raise InputError(f"no species '{props.species_name}' in the library ({', '.join(sorted(lib))}); "
                             "pick one of those or a species file")
        return species.load_species(lib[props.species_name]), None
    if src == "FILE":
        if not props.species_path:
            raise InputError("no species file chosen; pick a .json written by Save Species, or use the library")
        return species.load_species(bpy.path.abspath(props.species_path)), None
    return None, stored.selected_tree(context or bpy.context, "Species from a reconstructed tree")


def envelope_spec(props, tree=None, context=None):
    """What :func:`envelopes.envelope_from_any` takes: a shape name, an image path, a polygon
    ``(M, 2)`` (x, z metres) or the envelope of a reconstructed tree (``tree``, else the selected one)."""
    src = props.envelope_source
    if src == "SOURCE":
        if tree is None:
            try:
                tree = stored.selected_tree(context or bpy.context, "Envelope Source Outline")
            except InputError as exc:
                raise InputError(f"{exc}; or pick a shape, an image or a curve as the envelope") from None
        env = envelope_from_meta(tree.meta)
        if env is None:
            raise InputError(f"tree '{tree.name}' has no crown envelope; pick a shape, an image or a curve")
        return env
    if src == "IMAGE":
        path = bpy.path.abspath(props.envelope_image)
        if not props.envelope_image or not os.path.isfile(path):
            raise InputError(f"envelope image '{props.envelope_image}' does not exist; pick a silhouette image "
                             "(dark or opaque shape on white or transparent)")
        return path
    if src == "CURVE":
        return curve_polygon(props.envelope_curve)
    return src.lower()


def curve_polygon(ob) -> np.ndarray:
    """``(M, 2)`` (x, z) world metres of a closed curve object drawn in the front (X/Z) view."""
    if ob is None or ob.type != "CURVE":
        raise InputError("no curve chosen for the envelope; draw a closed curve in the front view "
                         "(Add › Curve › Circle, then shape it) and pick it")
    world, _ = evaluated_world_mesh(ob)
    if len(world) < 3:
        raise InputError(f"curve '{ob.name}' has fewer than 3 points; draw a closed shape around the crown")
    return world[:, [0, 2]]


def grow_params(props, model_frames: int | None = None, scene=None) -> growth.GrowParams:
    """The growth settings of the panel. Frames 0 (default): in a ``scene`` that already holds a
    tree, the scene's frame range at its frame rate (a new tree plays as long as what is there),
    else the source clip's length at its rate."""
    frames, fps = props.gen_frames, None
    if scene is not None and trees.scene_trees(scene):
        fps = timing.scene_fps(scene)
        frames = frames or scene.frame_end - max(scene.frame_start, 1) + 1
    frames = frames or model_frames or 250
    return growth.GrowParams(seed=props.gen_seed, height_m=props.gen_height, node_budget=props.gen_nodes,
                             n_frames=int(frames), fps=fps, wind=props.gen_wind, twig_depth=props.gen_twig_depth,
                             leaf_density=props.gen_leaf_density if props.build_leaves else 0.0,
                             loop_s=props.loop_seconds,         # a loop: grown on whole periods
                             envelope_variation=props.gen_envelope_variation, allometry=props.gen_allometry,
                             cuts=(CutSpec(bpy.path.abspath(props.gen_cut)),) if props.gen_cut else ())


def grow_inputs(props, context) -> tuple:
    """``(model or None, tree or None, envelope spec, GrowParams)`` of the panel: what Generate Tree,
    Generate Forest and Place Cut grow from (:func:`species_from`, :func:`envelope_spec`,
    :func:`grow_params`)."""
    model, tree_src = species_from(props, context)
    spec = envelope_spec(props, tree_src, context)
    params = grow_params(props, model.n_frames if model is not None else tree_src.n_frames, context.scene)
    return model, tree_src, spec, params


def audio_path(props) -> str | None:
    if not props.gen_audio:
        return None
    path = bpy.path.abspath(props.gen_audio)
    if not os.path.isfile(path):
        raise InputError(f"audio file '{props.gen_audio}' does not exist; pick a .wav (e.g. a windy-day "
                         "recording) or clear the field")
    return path


def ground_triangles(ob) -> np.ndarray:
    """``(T, 3, 3)`` world-space triangles of a mesh object (its evaluated mesh)."""
    if ob is None or ob.type != "MESH":
        raise InputError("no ground mesh chosen; pick a mesh with faces, or clear it to use an area")
    world, tri = evaluated_world_mesh(ob, triangles=True)
    return world[tri]


def _no_reconstruction(context, what: str, instead: str) -> str | None:
    """Why ``what`` (which uses a reconstructed tree) cannot run, or None: the file has none, or
    several and none is selected."""
    coll, _ = stored.selected(context)
    if coll is not None:
        return None
    n = len(stored.tree_collections())
    if n == 0:
        return f"{what} needs a reconstruction in this file; press Reconstruct first, or {instead}"
    return f"{what} needs one of the {n} reconstructed trees; select it (click its rig or mesh), or {instead}"


def why_not(context, props) -> str | None:
    """Why Generate Tree and Generate Forest are disabled (their poll message), or None: a job is
    running, no species (none in the library, a missing file, no reconstructed tree), or the
    envelope or the wind audio is missing. Cheap: file checks are cached."""
    if props is None:
        return "the add-on's settings are missing; enable Tree from Video again"
    if jobs.running():
        return "a job is running; wait for it to finish or press Cancel"
    src = props.species_source
    if src == "LIBRARY" and props.species_name in ("", "NONE"):
        return "no species in the library; pick a species file or a reconstructed tree as the Species"
    if src == "FILE":
        problem = missing_file(props.species_path, "species file", "Generate")
        if problem:
            return problem
    if src == "RECONSTRUCTION":
        problem = _no_reconstruction(context, "the species of a reconstructed tree", "pick a species from the library or a file")
        if problem:
            return problem
    env = props.envelope_source
    if env == "SOURCE" and src != "RECONSTRUCTION":
        problem = _no_reconstruction(context, "Source Outline", "pick a shape, an image or a curve as the Envelope")
        if problem:
            return problem
    if env == "IMAGE":
        problem = missing_file(props.envelope_image, "silhouette image", "Generate")
        if problem:
            return problem
    if env == "CURVE" and props.envelope_curve is None:
        return "no envelope curve chosen; draw a closed curve in the front view and pick it (Envelope › Curve)"
    if props.gen_cut:
        problem = missing_file(props.gen_cut, "tree-cut", "Generate")
        if problem:
            return problem
    if props.gen_audio:
        return missing_file(props.gen_audio, "wind audio", "Generate")
    return None


def grow_work(model, tree_src, spec, params, audio, slots_fn=None):
    """Worker: fit the species if needed, build the envelope, grow one tree or a forest."""
    def work(progress):
        m = model
        if m is None:
            m = species.fit_species(tree_src, tree_src.name)
        p = params
        env = envelopes.envelope_from_any(spec, p.height_m or 10.0)
        if slots_fn is None:
            return m, [growth.grow_tree(m, env, p, audio, progress)], None
        slots = slots_fn()
        trees = forest.generate_forest(m, env, slots, p, audio, sub_progress(progress, 0.0, 1.0))
        return m, trees, slots
    return work


# ----------------------------------------------------------------------------- operators

class TREE_OT_generate(jobs.JobOperator, bpy.types.Operator):
    """Grow a new animated tree of the chosen species inside the chosen envelope, at the 3D cursor (Esc cancels)"""

    bl_idname = "tree_video.generate"
    bl_label = "Generate Tree"
    bl_options = {"REGISTER", "UNDO"}
    what = "generation"

    @classmethod
    def poll(cls, context):
        why = why_not(context, getattr(context.scene, "tree_video", None))
        return refuse(cls, why) if why else True

    def make_job(self, context) -> Job:
        props = context.scene.tree_video
        model, tree_src, spec, params = grow_inputs(props, context)
        self._cursor = np.array(context.scene.cursor.location)
        if props.envelope_source == "CURVE":          # grow at the curve's size, standing where it is drawn
            spec = envelopes.envelope_from_polygon(spec)
            params.height_m = None
            y = float(np.array(props.envelope_curve.matrix_world)[1, 3])
            self._cursor = np.array([spec.offset[0], y, spec.offset[1]])
        env = envelopes.envelope_from_any(spec, params.height_m or 10.0)    # kept with the tree (Place Cut)
        self._growth = (env, params, audio_path(props))
        return Job(grow_work(model, tree_src, env, *self._growth[1:]))

    def done(self, context, result):
        model, trees, _ = result
        name = unique_collection_name(f"{model.name} {context.scene.tree_video.gen_seed}")
        props = context.scene.tree_video
        cuts = [{"path": bpy.path.abspath(props.gen_cut), "at": None}] if props.gen_cut else []
        env, params, audio = self._growth
        return build_generated(self, context, model, trees[0], name, cuts, location=getattr(self, "_cursor", None),
                               inputs=inputs_doc(model, env, params, audio))


def build_generated(op, context, model, tree, name: str, cuts: list[dict], replace: bool = False,
                    location=None, inputs: dict | None = None) -> set:
    """Build the generated ``tree`` of ``model`` as the collection ``name`` (``replace``: in place of
    the one of that name) with the panel's look, standing at ``location`` (an armature's
    ``matrix_world``, or a point); keep its rest, ``cuts`` and growth ``inputs``
    (:func:`core.generate.regrow.inputs_doc`) for Save Cut and Place Cut."""
    props = context.scene.tree_video
    try:
        tree, note = maybe_loop(tree, props.loop_seconds)
        if note:
            op.report({"INFO"}, note)
        game = game_settings(props)
        built = build_tree(context, tree, name, replace=replace, curliness=props.curliness, bark=props.bark,
                           forks=props.forks, relief_cm=props.bark_relief, keep_view=True,
                           bark_maps=species_bark(props, model), **build_kwargs(game))
        keep_engine_files(built, tree, game)
    except InputError as exc:
        op.report({"ERROR"}, str(exc))
        return {"CANCELLED"}
    rig = built["armature"]
    if location is not None and np.shape(location) == (4, 4):
        rig.matrix_world = location
    else:
        rig.location = np.zeros(3) if location is None else location
    stored.store_grown(built["collection"], tree, cuts, inputs)
    placed = f", {len(cuts)} cut(s) in it" if cuts else ""
    op.report({"INFO"}, f"'{name}': {tree.n_nodes - 1} branch bones, "
                        f"{tree.leaves.count if tree.leaves is not None else 0} leaf clusters × {tree.n_frames} "
                        f"frames{placed}")
    return {"FINISHED"}


class TREE_OT_generate_forest(jobs.JobOperator, bpy.types.Operator):
    """Scatter distinct animated trees of the species on the ground mesh (or an area at the 3D cursor), Poisson-disk spaced, each swaying with its own phase (Esc cancels)"""  # noqa: E501  (the tooltip)

    bl_idname = "tree_video.generate_forest"
    bl_label = "Generate Forest"
    bl_options = {"REGISTER", "UNDO"}
    what = "forest"

    _pending = None

    @classmethod
    def poll(cls, context):
        why = why_not(context, getattr(context.scene, "tree_video", None))
        return refuse(cls, why) if why else True

    def make_job(self, context) -> Job:
        props = context.scene.tree_video
        model, tree_src, spec, params = grow_inputs(props, context)
        audio = audio_path(props)
        n, spacing, seed = props.forest_count, props.forest_spacing, props.gen_seed
        # a recorded wind's gust reaches every tree at once: trees of a variant would carry it apart
        variants = 0 if audio else props.forest_variants
        if props.forest_ground is not None:
            tris = ground_triangles(props.forest_ground)

            def positions():
                return forest.scatter_on_mesh(n, tris, spacing, seed)
        else:
            cursor = np.array(context.scene.cursor.location)
            w, d = props.forest_width, props.forest_depth

            def positions():
                xy = forest.scatter_area(n, w, d, spacing, seed)
                return np.concatenate([xy + cursor[:2], np.full((len(xy), 1), cursor[2])], axis=1)
        self._name = unique_collection_name(props.forest_name.strip() or "Forest")
        return Job(grow_work(model, tree_src, spec, params, audio,
                              slots_fn=lambda: forest.forest_slots(positions(), seed, variants=variants)))

    # the worker's trees are built on the main thread: all at once (execute) or a few per tick (invoke)
    def done(self, context, result):
        props = context.scene.tree_video
        try:
            bark_maps = species_bark(props, result[0])
        except InputError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        state = ForestBuild(context, self._name, *result, curliness=props.curliness, bark=props.bark,
                            forks=props.forks, relief_cm=props.bark_relief, loop_s=props.loop_seconds,
                            game=game_settings(props), bark_maps=bark_maps)
        if self._timer is None and getattr(self, "_invoked", False):
            self._pending = state
            # still a running job while the trees are built: the other buttons stay greyed and
            # the status shows the building from its first tree on (issue 32: nothing showed
            # between growing and building, and the buttons were enabled again)
            self._job = jobs.hold(jobs.Busy())
            wm = context.window_manager
            self._timer = wm.event_timer_add(0.01, window=context.window)
            wm.progress_begin(0, 100)
            jobs.status(context, f"building 0/{len(state.trees)}", 0.0)
            return {"RUNNING_MODAL"}
        try:
            while not state.finished:
                state.step(context, budget_s=math.inf)
        except BaseException:
            state.remove()
            raise
        return self._report_done(state)

    def invoke(self, context, event):
        self._invoked = True
        return super().invoke(context, event)

    def modal(self, context, event):
        state = self._pending
        if state is None:
            return super().modal(context, event)
        if event.type == "ESC" or jobs.cancel_requested(context):
            state.remove()
            self._cleanup(context)
            self.report({"INFO"}, "forest cancelled; the scene is unchanged")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            state.step(context, BUILD_SLICE_S)
        except InputError as exc:
            state.remove()
            self._cleanup(context)
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        except BaseException:
            state.remove()
            self._cleanup(context)
            raise
        jobs.status(context, f"building {state.k}/{len(state.trees)}", state.k / max(len(state.trees), 1))
        context.window_manager.progress_update(int(100 * state.k / max(len(state.trees), 1)))
        if not state.finished:
            return {"RUNNING_MODAL"}
        self._cleanup(context)
        return self._report_done(state)

    def _report_done(self, state):
        bones = sum(len(c["armature"].data.bones) for c in state.built)
        self.report({"INFO"}, f"'{state.coll.name}': {len(state.built)} trees, {bones} bones, "
                              f"{state.elapsed:.1f} s to build")
        return {"FINISHED"}


class TREE_OT_save_species(bpy.types.Operator):
    """Fit the species model (Dirichlet bifurcation ratios and motion spectra) to the selected reconstructed tree (or the file's only one) and save it as a shareable .json"""  # noqa: E501  (the tooltip)

    bl_idname = "tree_video.save_species"
    bl_label = "Save Species"
    filepath: bpy.props.StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE"})
    filter_glob: bpy.props.StringProperty(default="*.json", options={"HIDDEN"})
    overwrite: bpy.props.BoolProperty(name="Overwrite", default=False, description="Replace an existing file")

    @classmethod
    def poll(cls, context):
        coll, why = stored.selected(context)
        if coll is None:
            cls.poll_message_set(f"{why} (its species is fitted from it)")
            return False
        return True

    def invoke(self, context, event):
        if not self.filepath:
            coll, _ = stored.selected(context)
            self.filepath = bpy.path.abspath(f"//{coll.name}.json".replace(" ", "_"))
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        path = bpy.path.abspath(self.filepath)
        try:
            tree = stored.selected_tree(context, "Save Species")
            if not path or os.path.isdir(path):
                raise InputError("no file name given; type a name ending in .json")
            if not path.lower().endswith(".json"):
                path += ".json"
            if os.path.exists(path) and not self.overwrite:
                raise InputError(f"'{path}' exists; tick Overwrite or choose another name")
            model = species.fit_species(tree, os.path.splitext(os.path.basename(path))[0])
            species.save_species(path, model)
        except (InputError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        props = context.scene.tree_video
        props.species_source, props.species_path = "FILE", path
        self.report({"INFO"}, f"species '{model.name}' ({model.n_bifurcations} bifurcations) saved to {path}")
        return {"FINISHED"}


classes = (TREE_OT_generate, TREE_OT_generate_forest, TREE_OT_save_species)

register, unregister = bpy.utils.register_classes_factory(classes)
