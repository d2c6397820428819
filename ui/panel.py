"""The "Tree from Video" sidebar panel (View3D › Sidebar › Tree) and its sub-panels; the main
panel with Source and Outline also in the Movie Clip editor's sidebar (Tree tab)."""
import bpy

from ..core.generate.photo import is_photo

_INFO_CACHE: dict = {}


def _video_info(path: str):
    """Size, frame count and fps of the chosen video (probed once per path), or None."""
    import os

    from ..core.errors import InputError
    from ..core.reconstruct.video import open_video
    full = bpy.path.abspath(path) if path else ""
    if not full or not os.path.isfile(full):
        return None
    key = (full, os.path.getmtime(full))
    if key not in _INFO_CACHE:
        try:
            _INFO_CACHE[key] = open_video(full)
        except InputError:
            _INFO_CACHE[key] = None
    return _INFO_CACHE[key]


def path_field(layout, props, name: str, **kw) -> bool:
    """Draw the file-path property ``name``; a path that names no file is drawn red with "File not
    found" under it, as soon as it is typed (the check is cached per path: draw stays cheap).
    Returns True if the field is empty or names an existing file."""
    from ..operators.scene import checks
    path = getattr(props, name)
    missing = bool(path) and not checks.exists(path)
    row = layout.row()
    row.alert = missing
    row.prop(props, name, **kw)
    if missing:
        layout.label(text="File not found", icon="ERROR")
    return not missing


class _TreePanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Tree"

    def column(self):
        """A column in Blender's split-label style (labels left of the fields, no truncation)."""
        self.layout.use_property_split = True
        self.layout.use_property_decorate = False
        return self.layout.column()


class TREE_PT_main(_TreePanel, bpy.types.Panel):
    bl_label = "Tree from Video"
    bl_idname = "TREE_PT_main"

    def draw_header_preset(self, context):
        row = self.layout.row(align=True)
        row.menu("TREE_MT_presets", text="Presets", icon="PRESET")
        row.operator("tree_video.preset_add", text="", icon="ADD")
        row.operator("tree_video.preset_add", text="", icon="REMOVE").remove_active = True

    def draw(self, context):
        layout = self.layout
        wm = context.window_manager
        running = bool(wm.tree_video_status)
        row = layout.row(align=True)
        row.scale_y = 1.4
        row.enabled = not running
        row.operator("tree_video.reconstruct", icon="OUTLINER_OB_ARMATURE")
        row = layout.row()
        row.enabled = not running
        row.operator("tree_video.preview", icon="TRACKING")
        props = getattr(context.scene, "tree_video", None)
        if props is not None and props.motion_measured >= 0 and not running:
            layout.label(text=f"Motion measured: {props.motion_measured:.0%}", icon="INFO")
        if running:                       # the progress once: a bar with the stage and its percentage
            from ..operators import jobs
            col = layout.column(align=True)
            if hasattr(col, "progress"):      # Blender 4.0+
                col.progress(factor=wm.tree_video_progress / 100.0, type="BAR", text=jobs.status_text(wm))
            else:
                col.label(text=jobs.status_text(wm), icon="TIME")
            col.operator("tree_video.cancel", icon="CANCEL")


class TREE_PT_source(_TreePanel, bpy.types.Panel):
    bl_label = "Source"
    bl_parent_id = "TREE_PT_main"

    def draw(self, context):
        props = context.scene.tree_video
        col = self.column()
        path_field(col, props, "video_path")
        if is_photo(props.video_path):                 # one frame: its tree sways as a species
            col.label(text="A photo: its tree sways as a species", icon="IMAGE_DATA")
            col.prop(props, "photo_species")
            col.prop(props, "photo_seconds")
            col.prop(props, "photo_wind")
            col.prop(props, "scale")
            return
        info = _video_info(props.video_path)
        if info is not None:
            col.label(text=f"{info.width}×{info.height}, {info.frame_count} frames, {info.fps:.3g} fps",
                      icon="FILE_MOVIE")
        col.prop(props, "use_frame_range")
        sub = col.column(align=True)
        sub.enabled = props.use_frame_range
        sub.prop(props, "frame_start")
        sub.prop(props, "frame_end")
        col.prop(props, "scale")


class TREE_PT_outline(_TreePanel, bpy.types.Panel):
    bl_label = "Outline"
    bl_parent_id = "TREE_PT_main"

    def draw(self, context):
        props = context.scene.tree_video
        col = self.column()
        col.prop(props, "outline_source")
        if props.outline_source == "FILE":
            path_field(col, props, "outline_path")
        elif props.outline_source == "AUTO":
            hint = col.column(align=True)
            hint.label(text="Found from what sways in wind:", icon="INFO")
            hint.label(text="check it with Track & Preview", icon="BLANK1")
        elif props.outline_source == "ANNOTATION":
            from ..operators.scene import annotation
            col.operator("tree_video.open_clip", icon="TRACKER")
            hint = col.column(align=True)
            hint.label(text="Draw around the tree on frame 1:", icon="GREASEPENCIL")
            hint.label(text="clip toolbar › Annotation › Draw", icon="BLANK1")
            hint.label(text="or hold D and drag", icon="BLANK1")
            ok, text = annotation.status(props.video_path)
            col.label(text=text, icon="CHECKMARK" if ok else "ERROR")
        else:
            col.prop(props, "outline_mask")
            col.operator("tree_video.open_clip", icon="TRACKER")


class TREE_PT_reconstruction(_TreePanel, bpy.types.Panel):
    bl_label = "Reconstruction"
    bl_parent_id = "TREE_PT_main"

    def draw(self, context):
        props = context.scene.tree_video
        col = self.column()
        col.prop(props, "levels")
        col.prop(props, "skeleton_kind")
        if props.skeleton_kind == "paper":
            col.prop(props, "fold_alpha")
        col.prop(props, "form")
        col.prop(props, "depth_source")
        col.prop(props, "limbs")
        if props.limbs != "trace":
            col.prop(props, "limb_species")
            if not props.limb_species.strip():
                col.label(text="Empty: the form's own species", icon="INFO")
        col.prop(props, "candidates")
        col.prop(props, "solver")
        row = col.row()
        row.use_property_split = False                # a labelled button across the panel, not a bare gear
        row.prop(props, "show_advanced", text="Advanced Solver Settings", icon="PREFERENCES", toggle=True)
        if props.show_advanced:
            box = col.box()
            box.enabled = props.solver == "probabilistic"
            box.prop(props, "sigma_track")
            box.prop(props, "sigma_shape")
            box.prop(props, "max_step")
            box.prop(props, "max_total")


class TREE_PT_output(_TreePanel, bpy.types.Panel):
    bl_label = "Output"
    bl_parent_id = "TREE_PT_main"

    def draw(self, context):
        props = context.scene.tree_video
        col = self.column()
        col.prop(props, "collection_name")
        col.prop(props, "replace_existing")
        col.prop(props, "height_m")
        col.prop(props, "fit_branches")
        col.prop(props, "twig_depth")
        col.prop(props, "loop_seconds")
        col.prop(props, "build_mesh")
        sub = col.column()
        sub.enabled = props.build_mesh
        sub.prop(props, "curliness", slider=True)
        sub.prop(props, "bark")
        sub.prop(props, "forks")
        sub.prop(props, "bark_relief")
        path_field(sub, props, "bark_image")
        if props.bark_image.strip():                 # the photo's bark: its moss, lichen and scale
            sub.prop(props, "bark_moss", slider=True)
            sub.prop(props, "bark_lichen", slider=True)
            sub.prop(props, "bark_scale")
        col.prop(props, "build_leaves")
        sub = col.column()
        sub.enabled = props.build_leaves
        sub.prop(props, "leaf_density", slider=True)
        sub.prop(props, "leaf_cards")
        sub.prop(props, "flutter_hz", text="Flutter (Hz)")
        sub.prop(props, "flutter_gain")
        row = sub.row(align=True)
        row.prop(props, "leaf_colour_mode")
        if props.leaf_colour_mode == "custom":
            row.prop(props, "leaf_colour_custom", text="")
        path_field(sub, props, "leaf_image")
        if props.leaf_polygons:
            sub.label(text=f"Last tree: {props.leaf_polygons:,} leaf polygons", icon="INFO")


class TREE_PT_game(_TreePanel, bpy.types.Panel):
    bl_label = "Game Export"
    bl_parent_id = "TREE_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        props = context.scene.tree_video
        col = self.column()
        col.prop(props, "game_engine")
        col.prop(props, "game_bones")
        col.prop(props, "game_lods")
        col.prop(props, "loop_seconds")
        col.prop(props, "game_collision")
        col.prop(props, "game_pivot_painter")
        col.prop(props, "game_bone_texture")
        col.prop(props, "game_impostor")
        col.label(text="For the next tree built", icon="INFO")
        col.label(text="Export writes its engine files", icon="BLANK1")


class TREE_PT_generate(_TreePanel, bpy.types.Panel):
    bl_label = "Generate"
    bl_parent_id = "TREE_PT_main"

    def draw(self, context):
        from ..operators.scene import stored
        props = context.scene.tree_video
        col = self.column()
        col.prop(props, "species_source")
        if props.species_source == "LIBRARY":
            col.prop(props, "species_name")
        elif props.species_source == "FILE":
            path_field(col, props, "species_path")
        if props.species_source == "RECONSTRUCTION" or props.envelope_source == "SOURCE":
            coll, why = stored.selected(context)        # the tree kept in the file that is used
            col.label(text=f"{coll.name} ({why})" if coll is not None else why,
                      icon="OUTLINER_COLLECTION" if coll is not None else "ERROR")
        col.operator("tree_video.save_species", icon="FILE_TICK")
        col.separator()
        col.prop(props, "envelope_source")
        if props.envelope_source == "IMAGE":
            path_field(col, props, "envelope_image")
        elif props.envelope_source == "CURVE":
            col.prop(props, "envelope_curve")
        col.prop(props, "gen_seed")
        col.prop(props, "gen_height")
        col.prop(props, "gen_nodes")
        col.prop(props, "gen_twig_depth")
        col.prop(props, "gen_frames")
        col.prop(props, "gen_leaf_density", slider=True)
        col.prop(props, "gen_envelope_variation", slider=True)
        col.prop(props, "gen_allometry")
        col.prop(props, "gen_wind")
        path_field(col, props, "gen_audio")
        path_field(col, props, "gen_cut")
        row = col.row(align=True)
        row.operator("tree_video.save_cut", icon="MOD_BOOLEAN")
        row.operator("tree_video.place_cut", icon="PIVOT_CURSOR")
        col.operator("tree_video.generate", icon="OUTLINER_OB_FORCE_FIELD")
        col.separator()
        col.prop(props, "forest_name")
        col.prop(props, "forest_count")
        col.prop(props, "forest_variants")
        col.prop(props, "forest_spacing")
        col.prop(props, "forest_ground")
        if props.forest_ground is None:        # one row each: side by side, the Depth label was lost
            sub = col.column(align=True)
            sub.prop(props, "forest_width")
            sub.prop(props, "forest_depth")
        col.operator("tree_video.generate_forest", icon="OUTLINER_COLLECTION")


class TREE_PT_export(_TreePanel, bpy.types.Panel):
    bl_label = "Export"
    bl_parent_id = "TREE_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        from ..operators.export_op import draw_settings
        draw_settings(self.layout, context)
        col = self.column()
        col.separator()
        col.operator("tree_video.trace_skeleton", icon="FILE", text="Save 2D Skeleton (.npz)")
        col.operator("tree_video.save_billboard", icon="IMAGE_RGB_ALPHA")


def _in_clip_editor(panel, name: str, parent: str | None = None):
    """A copy of the 3D view's ``panel`` for the Movie Clip editor's sidebar (Tree tab), with the same
    draw functions. Not a subclass: Blender loses track of a registered panel class that is subclassed
    and registered again (its 3D view panel then draws empty)."""
    shared = ("bl_label", "bl_options", "poll", "draw", "draw_header", "draw_header_preset")
    attrs = {k: v for k, v in vars(panel).items() if k in shared}
    attrs.update(bl_idname=name, bl_space_type="CLIP_EDITOR", __doc__=panel.__doc__)
    if parent:
        attrs["bl_parent_id"] = parent
    return type(name, (_TreePanel, bpy.types.Panel), attrs)


# Track & Preview, its source and its outline in the Movie Clip editor too
TREE_PT_clip_main = _in_clip_editor(TREE_PT_main, "TREE_PT_clip_main")
TREE_PT_clip_source = _in_clip_editor(TREE_PT_source, "TREE_PT_clip_source", "TREE_PT_clip_main")
TREE_PT_clip_outline = _in_clip_editor(TREE_PT_outline, "TREE_PT_clip_outline", "TREE_PT_clip_main")


classes = (TREE_PT_main, TREE_PT_source, TREE_PT_outline, TREE_PT_reconstruction, TREE_PT_output, TREE_PT_game,
           TREE_PT_generate,
           TREE_PT_export, TREE_PT_clip_main, TREE_PT_clip_source, TREE_PT_clip_outline)

register, unregister = bpy.utils.register_classes_factory(classes)
