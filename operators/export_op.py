"""Export the reconstructed tree (its collection's armature and mesh) from the panel."""
import os

import bpy

from ..core.errors import InputError
from .scene import export

EXTENSIONS = {"FBX": ".fbx", "GLB": ".glb", "USD": ".usdc"}


def tree_objects(name: str) -> list:
    coll = bpy.data.collections.get(name)
    objs = [o for o in coll.all_objects if o.type in ("ARMATURE", "MESH")] if coll else []
    if not any(o.type == "ARMATURE" for o in objs):
        raise InputError(f"no reconstructed tree in collection '{name}'; press Reconstruct first "
                         "or set the Output collection name")
    return objs


def export_path(props) -> str:
    folder = bpy.path.abspath(props.output_dir)
    if not folder:
        raise InputError("no export folder set; choose one in the Export panel")
    name = bpy.path.clean_name(props.collection_name) or "tree"
    return os.path.join(folder, name + EXTENSIONS[props.export_format])


class TREE_OT_export(bpy.types.Operator):
    """Export the reconstructed tree to the chosen format in the export folder"""

    bl_idname = "tree_video.export"
    bl_label = "Export Tree"

    @classmethod
    def poll(cls, context):
        props = getattr(context.scene, "tree_video", None)
        return props is not None and bpy.data.collections.get(props.collection_name) is not None

    def execute(self, context):
        props = context.scene.tree_video
        try:
            objects = tree_objects(props.collection_name)
            path = export_path(props)
            folder = os.path.dirname(path)
            if props.export_format == "USD" and not export.has_usd():
                raise InputError("this Blender was built without USD; export FBX or glTF instead")
            try:
                os.makedirs(folder, exist_ok=True)
            except OSError as exc:
                raise InputError(f"cannot create the export folder '{folder}' ({exc.strerror}); "
                                 "choose another folder") from None
            if not os.access(folder, os.W_OK):
                raise InputError(f"the export folder '{folder}' is not writable; choose another folder")
            writer = {"FBX": export.export_fbx, "GLB": export.export_gltf, "USD": export.export_usd}[props.export_format]
            writer(path, objects, overwrite=props.overwrite, context=context)
        except InputError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        except export.ExportError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"exported {path}")
        return {"FINISHED"}


classes = (TREE_OT_export,)

register, unregister = bpy.utils.register_classes_factory(classes)
