"""View3D sidebar panel, tab "Tree"."""
import bpy


class TREE_PT_main(bpy.types.Panel):
    bl_label = "Tree from Video"
    bl_idname = "TREE_PT_main"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Tree"

    def draw(self, context):
        props = context.scene.tree_video
        col = self.layout.column()
        col.prop(props, "video_path")
        col.prop(props, "outline_path")
        col.prop(props, "levels")
        col.prop(props, "skeleton_kind")
        col.prop(props, "output_dir")
        col.prop(props, "overwrite")
        col.operator("tree_video.trace_skeleton", icon="OUTLINER_OB_ARMATURE")


classes = (TREE_PT_main,)


register, unregister = bpy.utils.register_classes_factory(classes)
