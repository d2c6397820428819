"""Tree-cuts in the scene (issue 36, seed 001's editing operator).

* **Save Cut**: the bones selected on a tree's rig (Pose Mode; with *With Its Branches*, every bone
  beyond them too) and their branch mesh, kept as a cut file (:mod:`core.tree_cut`, ``.npz`` with a
  JSON header). Any reconstructed tree, or one made by Generate Tree (its rest is kept with it).
* **Place Cut**: the selected generated tree grown again as it grew (its species, envelope,
  settings and seed, kept with it: :mod:`core.generate.regrow`; a tree kept without them takes the
  panel's, with its own seed), so that it holds the panel's Cut with its base on the branch nearest
  the 3D cursor (its earlier cuts where they were); the rest grows around it
  (:mod:`core.generate.cuts`).
  It replaces the tree in place, its rig where it stood (Ctrl Z brings the old one back).

Generate Tree and Generate Forest place the panel's Cut where its base fits.
"""
from __future__ import annotations

import os
import re

import bpy
import numpy as np

from ..core.errors import InputError
from ..core.generate import envelopes
from ..core.generate.cuts import CutSpec
from ..core.generate.regrow import inputs_doc, inputs_from_doc
from ..core.job import Job
from ..core.tree_cut import cut_from_tree, save_cut
from . import jobs
from .generate_op import audio_path, build_generated, grow_inputs, grow_work, why_not
from .scene import stored
from .scene.checks import missing_file, refuse

#: the rig's branch bones (``core.bones.bone_names``); leaf bones and others are left out of a cut
BRANCH_BONE = re.compile(r"B\d+$")


def _selectable(ob, name: str):
    """What holds bone ``name``'s selection: its pose bone in Blender 5 (``PoseBone.select``), its
    bone before (``Bone.select``, gone in 5.0)."""
    pb = ob.pose.bones[name]
    return pb if hasattr(pb, "select") else ob.data.bones[name]


def _selected(ob):
    return (b.name for b in ob.data.bones if BRANCH_BONE.match(b.name) and _selectable(ob, b.name).select)


def selected_branch_bones(ob) -> list[str]:
    """Names of the branch bones selected on the armature object ``ob`` (Pose or Object Mode)."""
    return list(_selected(ob))


def select_bones(ob, names) -> None:
    """Select exactly the bones ``names`` of the armature object ``ob`` (scripts, tests)."""
    names = set(names)
    for b in ob.data.bones:
        _selectable(ob, b.name).select = b.name in names


def _rig_problem(context) -> str | None:
    ob = getattr(context, "active_object", None)
    if ob is None or ob.type != "ARMATURE":
        return "select a tree's rig, then the bones of a branch in Pose Mode"
    if next(_selected(ob), None) is None:                # a poll: stop at the first selected one
        return "select the bones of a branch (Pose Mode); the cut takes them and every bone beyond them"
    return None


class TREE_OT_save_cut(bpy.types.Operator):
    """Save the selected bones of a tree (and every bone beyond them) with their branch mesh as a tree-cut (.npz) that generated trees can be made to contain"""  # noqa: E501  (the tooltip)

    bl_idname = "tree_video.save_cut"
    bl_label = "Save Cut"
    filepath: bpy.props.StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE"})
    filter_glob: bpy.props.StringProperty(default="*.npz", options={"HIDDEN"})
    whole_branch: bpy.props.BoolProperty(name="With Its Branches", default=True,
                                         description="Take every bone beyond the selected ones too (a branch with "
                                                     "its side branches); off: the selected bones only")
    overwrite: bpy.props.BoolProperty(name="Overwrite", default=False, description="Replace an existing file")

    @classmethod
    def poll(cls, context):
        why = _rig_problem(context)
        return refuse(cls, why) if why else True

    def invoke(self, context, event):
        if not self.filepath:
            self.filepath = bpy.path.abspath(f"//{context.active_object.name}_cut.npz".replace(" ", "_"))
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        from ..core.asset.cut_mesh import with_mesh
        path = bpy.path.abspath(self.filepath)
        try:
            why = _rig_problem(context)
            if why:
                raise InputError(why)
            if not path or os.path.isdir(path):
                raise InputError("no file name given; type a name ending in .npz")
            if not path.lower().endswith(".npz"):
                path += ".npz"
            if os.path.exists(path) and not self.overwrite:
                raise InputError(f"'{path}' exists; tick Overwrite or choose another name")
            coll, tree = stored.rig_tree(context)
            cut = with_mesh(tree, cut_from_tree(tree, selected_branch_bones(context.active_object),
                                                whole_branch=self.whole_branch))
            save_cut(path, cut, overwrite=self.overwrite)
        except (InputError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        context.scene.tree_video.gen_cut = path
        self.report({"INFO"}, f"cut of {cut.n_bones} bones from '{coll.name}' saved to {path}")
        return {"FINISHED"}


def _grown_rig(context):
    """``(collection, rig)`` of the generated tree whose object is active, or None."""
    ob = getattr(context, "active_object", None)
    if ob is None:
        return None
    found = stored.owners([ob], stored.is_grown)
    if not found:
        return None
    rig = next((o for o in found[0].objects if o.type == "ARMATURE"), None)
    return None if rig is None else (found[0], rig)


class TREE_OT_place_cut(jobs.JobOperator, bpy.types.Operator):
    """Grow the selected generated tree again as it grew (its species, envelope, settings and seed) so that it holds the Cut with its base on the branch nearest the 3D cursor; it replaces the tree where it stands (Esc cancels)"""  # noqa: E501  (the tooltip)

    bl_idname = "tree_video.place_cut"
    bl_label = "Place Cut"
    bl_options = {"REGISTER", "UNDO"}
    what = "regrowth"

    @classmethod
    def poll(cls, context):
        props = getattr(context.scene, "tree_video", None)
        if props is not None:
            problem = (missing_file(props.gen_cut, "tree-cut", "Place Cut") if props.gen_cut
                       else "no Cut chosen; pick a .npz saved by Save Cut")
            if problem:
                return refuse(cls, problem)
        found = _grown_rig(context)
        if found is None:
            return refuse(cls, "select a tree made by Generate Tree (its rig or mesh), then put the 3D cursor "
                               "on the branch the cut should grow from")
        if jobs.running():
            return refuse(cls, "a job is running; wait for it to finish or press Cancel")
        why = None if stored.has_grown_inputs(found[0]) else why_not(context, props)   # kept: no panel
        return refuse(cls, why) if why else True

    def make_job(self, context) -> Job:
        props = context.scene.tree_video
        found = _grown_rig(context)
        if found is None:
            raise InputError("select a tree made by Generate Tree first")
        coll, rig = found
        kept = stored.grown_inputs(coll)
        if kept is not None:                           # what it grew from: the same tree, now with the cut
            model, spec, params, audio = inputs_from_doc(kept)
            tree_src = None
        else:                                          # a tree kept without them: the panel's settings
            model, tree_src, spec, params = grow_inputs(props, context)
            audio = audio_path(props)
            if props.envelope_source == "CURVE":       # the curve's size, as Generate Tree grew it
                spec, params.height_m = envelopes.envelope_from_polygon(spec), None
            spec = envelopes.envelope_from_any(spec, params.height_m or 10.0)
            params.seed = int(stored.kept_tree(coll).meta.get("seed", params.seed))
        context.view_layer.update()                   # the rig's world matrix as it stands now
        world = np.array(rig.matrix_world)
        at = (np.linalg.inv(world) @ np.append(np.array(context.scene.cursor.location), 1.0))[:3]
        cuts = stored.grown_cuts(coll) + [{"path": bpy.path.abspath(props.gen_cut), "at": [float(v) for v in at]}]
        params.cuts = tuple(CutSpec(c["path"], None if c["at"] is None else (c["at"][0], c["at"][1], c["at"][2]))
                            for c in cuts)
        self._place = (coll.name, rig.matrix_world.copy(), cuts, spec, params, audio)
        return Job(grow_work(model, tree_src, spec, params, audio))

    def done(self, context, result):
        model, trees, _ = result
        name, world, cuts, env, params, audio = self._place
        return build_generated(self, context, model, trees[0], name, cuts, replace=True, location=world,
                               inputs=inputs_doc(model, env, params, audio))


classes = (TREE_OT_save_cut, TREE_OT_place_cut)

register, unregister = bpy.utils.register_classes_factory(classes)
