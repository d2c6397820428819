"""Settings saved with the .blend, in ``scene.tree_video``."""
import bpy


class TreeVideoSettings(bpy.types.PropertyGroup):
    video_path: bpy.props.StringProperty(name="Video", subtype="FILE_PATH",
                                         description="Video of the tree moving in wind (mp4/mov/avi)")
    outline_path: bpy.props.StringProperty(name="Outline", subtype="FILE_PATH",
                                           description="Outline of the tree in frame 1: polygon .json (pixels) or mask image")
    output_dir: bpy.props.StringProperty(name="Output", subtype="DIR_PATH", default="//tree_from_video",
                                         description="Folder for the skeleton and exports")
    levels: bpy.props.IntProperty(name="Hierarchy Levels", default=6, min=2, max=9,
                                  description="Levels of the binary motion hierarchy incl. the root (paper: 5-7)")
    skeleton_kind: bpy.props.EnumProperty(
        name="Skeleton", default="traced",
        items=[("traced", "Traced", "Branches traced in the video, hierarchy attached through the crown"),
               ("paper", "Paper", "Cluster centroids folded toward parents (alpha = 0.4), as in the paper")],
        description="How the 2D skeleton's nodes are placed")
    overwrite: bpy.props.BoolProperty(name="Overwrite", default=False,
                                      description="Replace existing files in the output folder")


classes = (TreeVideoSettings,)


def register():
    for c in classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.tree_video = bpy.props.PointerProperty(type=TreeVideoSettings)


def unregister():
    del bpy.types.Scene.tree_video
    for c in reversed(classes):
        bpy.utils.unregister_class(c)
