"""Operator: save the moving 2D skeleton of the video as skeleton.npz (Export panel; blocking)."""
import os

import bpy

from ..core import pipeline
from ..core.errors import InputError
from ..core.reconstruct import skeleton_io
from .scene.checks import missing_file, refuse


class TREE_OT_trace_skeleton(bpy.types.Operator):
    """Track the video and build the moving 2D skeleton, saved as skeleton.npz in the output folder"""

    bl_idname = "tree_video.trace_skeleton"
    bl_label = "Trace 2D Skeleton"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        props = getattr(context.scene, "tree_video", None)
        if props is None:
            return refuse(cls, "the add-on's settings are missing; enable Tree from Video again")
        why = (missing_file(props.video_path, "video", "Source")
               or missing_file(props.outline_path, "outline file", "Outline"))
        return refuse(cls, why) if why else True

    def execute(self, context):
        props = context.scene.tree_video
        out = bpy.path.abspath(props.output_dir)
        settings = pipeline.Settings(levels=props.levels, skeleton=props.skeleton_kind)
        try:
            res = pipeline.run(bpy.path.abspath(props.video_path), bpy.path.abspath(props.outline_path), settings)
            os.makedirs(out, exist_ok=True)
            path = os.path.join(out, "skeleton.npz")
            if os.path.exists(path) and not props.overwrite:
                raise InputError(f"{path} exists; tick Overwrite or choose another output folder")
            skeleton_io.save_skeleton(path, res.skeleton)
        except InputError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        except OSError as exc:
            self.report({"ERROR"}, f"cannot write to '{out}' ({exc.strerror}); choose another output folder")
            return {"CANCELLED"}
        for w in res.warnings:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, f"{res.skeleton.n_nodes} nodes over {res.tracks.n_frames} frames → {path}")
        return {"FINISHED"}


classes = (TREE_OT_trace_skeleton,)


register, unregister = bpy.utils.register_classes_factory(classes)
