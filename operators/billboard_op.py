"""Save Billboard (issue 36 part 2, the panel's ``--billboard``): the selected tree's front at rest
rendered in Blender as ``billboard.png`` (RGBA, alpha its coverage), ``billboard_normal.png`` and
``billboard.json`` (:mod:`core.asset.billboard`) into a folder, the same files the batch writes
beside a tree; a billboard is also an exemplar for Tree Variations."""
from __future__ import annotations

import os

import bpy

from ..core.asset.billboard import BILLBOARD_PX, DEFAULT_PX
from ..core.asset.billboard import FILES as BILLBOARD_FILES
from ..core.errors import InputError
from ..core.fileio import write_files
from .scene import trees
from .scene.checks import refuse
from .scene.outputs import billboard_meshes, billboard_render, rest_points


def _one_tree(context):
    found = trees.selected_trees(context)
    if len(found) != 1:
        return None, ("select one tree (its rig or mesh) for its billboard" if found else
                      "no tree selected; click a tree's rig or mesh")
    coll = found[0]
    rig = next((o for o in coll.all_objects if o.type == "ARMATURE"), None)
    if rig is None or not billboard_meshes(coll):
        return None, f"tree '{coll.name}' has no rig and mesh to render (a forest's instances: pick its source tree)"
    return (coll, rig), None


class TREE_OT_save_billboard(bpy.types.Operator):
    """Render the selected tree's front at rest as a billboard: billboard.png (RGBA), its normal map and billboard.json, in the folder you pick"""  # noqa: E501  (the tooltip)

    bl_idname = "tree_video.save_billboard"
    bl_label = "Save Billboard"
    directory: bpy.props.StringProperty(subtype="DIR_PATH", options={"SKIP_SAVE"})
    px: bpy.props.IntProperty(name="Pixels", default=DEFAULT_PX, min=BILLBOARD_PX[0], max=BILLBOARD_PX[1],
                              description="The billboard's pixels on its longer side")
    overwrite: bpy.props.BoolProperty(name="Overwrite", default=False, description="Replace existing billboard files")

    @classmethod
    def poll(cls, context):
        _, why = _one_tree(context)
        return refuse(cls, why) if why else True

    def invoke(self, context, event):
        if not self.directory:
            self.directory = bpy.path.abspath("//")
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        folder = bpy.path.abspath(self.directory)
        try:
            found, why = _one_tree(context)
            if why:
                raise InputError(why)
            coll, rig = found
            if not folder or not os.path.isdir(folder):
                raise InputError(f"folder '{self.directory}' does not exist; pick a folder for the billboard")
            there = [f for f in BILLBOARD_FILES if os.path.exists(os.path.join(folder, f))]
            if there and not self.overwrite:
                raise InputError(f"{there[0]} exists in {folder}; tick Overwrite or pick another folder")
            context.view_layer.update()
            meshes = billboard_meshes(coll)
            written = write_files(folder, billboard_render(rig, meshes, rest_points(meshes), coll.name, self.px))
        except (InputError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"billboard of '{coll.name}' ({self.px} px): {written[0]}")
        return {"FINISHED"}


classes = (TREE_OT_save_billboard,)

register, unregister = bpy.utils.register_classes_factory(classes)
