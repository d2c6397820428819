"""Export just the tree (its armature and branch mesh) to FBX, glTF binary or USD, atomically.

Each exporter writes a hidden temporary file in the target's folder, which replaces the target
(``os.replace``) only when the export succeeded; on failure the temporary file is deleted and an
existing target is untouched. An existing target is refused unless ``overwrite=True``. Exporter
options are passed only if this Blender's exporter has them (feature checks, not versions), and
the export runs over the frame range of the armature's action, in a scene of its own that holds
only the exported objects (so it costs only its tree, whatever else the file holds), removed after.
"""
from __future__ import annotations

import os
import re
import uuid
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Iterable

import bpy
import numpy as np

from ...core.errors import InputError
from .action_api import action_fcurves, rig_action
from .instances import played_as_action
from .timing import set_frame_range


@dataclass
class Exported:
    """What an export wrote: ``paths`` (absolute), each tree's ``seconds`` (its writer's own time;
    in a background Blender, without the process's start) and the ``total`` seconds from the
    first tree to the last file renamed."""

    paths: list = field(default_factory=list)
    seconds: list = field(default_factory=list)
    total: float = 0.0

    def timing(self) -> str:
        """``"56 s in all, 4.1–5.3 s a tree"``, or ``"4.2 s"`` for one tree."""
        if len(self.seconds) < 2:
            return f"{self.total:.1f} s"
        return f"{self.total:.0f} s in all, {min(self.seconds):.1f}–{max(self.seconds):.1f} s a tree"


class ExportError(RuntimeError):
    """The exporter failed; the message names the format and the file."""


def has_usd() -> bool:
    """True if this Blender was built with USD (Debian's Blender 4.3 is not)."""
    return _operator_properties(bpy.ops.wm, "usd_export") is not None


def export_fbx(path: str | os.PathLike, objects: Iterable[bpy.types.Object], *, overwrite: bool = False,
               context=None, extra: dict | None = None) -> str:
    """Write ``objects`` (the tree's armature and mesh) to ``path`` (``.fbx``) and return the path.

    Baked animation with exactly one key per frame and bone (``bake_anim_simplify_factor=0``,
    start/end keys forced, step 1), no leaf bones added (bone count stays exact), only the
    rig's current action, its first frame at FBX time 0 (the exporter writes a frame's number as
    its time: keys on frames 1..F came back on 2..F+1 with Blender's own import, and engines saw
    an empty first frame). Textures are embedded (``path_mode`` COPY + ``embed_textures``: with AUTO the
    leaf texture was left out and the leaves imported white). The animation stack is named after
    the rig's action (:func:`animation_name`: ``<tree>_loop`` for a loop). ``extra``: options an
    engine preset sets (:func:`core.asset.game.fbx_options`: units, axes)."""
    options = dict(use_selection=True, object_types={"ARMATURE", "MESH", "EMPTY"}, add_leaf_bones=False,
                   bake_anim=True, bake_anim_use_all_bones=True, bake_anim_use_nla_strips=False,
                   bake_anim_use_all_actions=False, bake_anim_force_startend_keying=True,
                   bake_anim_step=1.0, bake_anim_simplify_factor=0.0, use_armature_deform_only=False,
                   use_mesh_modifiers=False, path_mode="COPY", embed_textures=True, batch_mode="OFF")
    options.update(extra or {})
    return _export("FBX", bpy.ops.export_scene, "fbx", path, (".fbx",), objects, options, overwrite, context,
                   keys_from_zero=True)


def export_gltf(path: str | os.PathLike, objects: Iterable[bpy.types.Object], *, overwrite: bool = False,
                context=None, game: bool = False) -> str:
    """Write ``objects`` to a binary glTF ``path`` (``.glb``) and return the path.

    One skin (every bone a joint), the rig's current action sampled at every frame and no other
    action of the file (no optimisation that would drop constant keys), times starting at 0 s
    (``export_anim_slide_to_zero``, where this Blender's exporter has it); the animation is named
    after the rig's action (:func:`animation_name`: ``<tree>_loop`` for a loop). ``game``: opaque
    images as JPEG (the alpha-tested leaf stays PNG) and the file packed for engines
    (:func:`core.asset.glb_pack.pack_glb`: byte weights and colours, short UVs, no constant scale
    channels)."""
    options = dict(export_format="GLB", use_selection=True, export_animations=True,
                   export_animation_mode="ACTIVE_ACTIONS", export_frame_range=True, export_frame_step=1,
                   export_force_sampling=True, export_anim_slide_to_zero=True,
                   export_optimize_animation_size=False, export_optimize_animation_keep_anim_armature=True,
                   export_optimize_animation_keep_anim_object=False, export_def_bones=False,
                   export_leaf_bone=False, export_skins=True, export_apply=False, export_yup=True,
                   export_cameras=False, export_lights=False, export_extras=False,
                   # the leaf flap's morph targets move positions only: its normals' targets were
                   # 1.5 MB of a 9.9 MB game GLB (a card's shading barely turns with a flap)
                   export_morph_normal=False,
                   # only the scene the export runs in (default: every scene of the file, each a
                   # glTF scene, the window switched to each in turn)
                   use_active_scene=True,
                   # with one armature exported, this option (default on) adds every armature action
                   # in the file: in ACTIVE_ACTIONS mode they are merged by bone name, so a
                   # reconstruction exported after Generate carried the generated tree's rotations
                   # (Blender 4.3: quaternion components off by up to 1.9, the other tree's key count)
                   export_anim_single_armature=False)
    options["export_nla_strips_merged_animation_name"] = animation_name(objects) or "Animation"
    objects = without_collision(objects)
    if game:
        options["export_image_format"] = "JPEG"
    return _export("glTF", bpy.ops.export_scene, "gltf", path, (".glb",), objects, options, overwrite, context,
                   post=_pack_file if game else None, alpha_clip=True)


def _pack_file(path: str) -> None:
    from ...core.asset.glb_pack import pack_glb_file
    pack_glb_file(path)


def export_usd(path: str | os.PathLike, objects: Iterable[bpy.types.Object], *, overwrite: bool = False,
               context=None) -> str:
    """Write ``objects`` to ``path`` (``.usd``/``.usda``/``.usdc``) and return the path.

    A UsdSkel skeleton with one joint per bone and a SkelAnimation sampled at every frame; the
    materials' images written to ``textures/`` beside it under names of letters, digits, ``_`` and
    ``-`` (a name with spaces is a fragile asset path), an existing texture kept unless
    ``overwrite``. Raises :class:`InputError` if this Blender has no USD exporter."""
    if not has_usd():
        raise InputError(f"cannot write '{os.fspath(path)}': this Blender was built without USD "
                         f"(Blender {bpy.app.version_string} has no wm.usd_export, as in Debian's "
                         "packages); export FBX or glTF instead, or use a blender.org build for USD")
    options = dict(selected_objects_only=True, export_animation=True, export_armatures=True, export_shapekeys=True,
                   only_deform_bones=False, export_meshes=True, export_materials=True,
                   export_uvmaps=True, export_normals=True, export_lights=False, export_cameras=False,
                   # the leaf texture is packed in the .blend: write it beside the file (textures/)
                   # instead of referencing a ./textures/ file that KEEP never writes
                   export_textures_mode="NEW", export_textures=True, overwrite_textures=overwrite,
                   relative_paths=True, generate_preview_surface=True, evaluation_mode="RENDER")
    objects = without_collision(objects)
    with _safe_image_names(objects):
        return _export("USD", bpy.ops.wm, "usd_export", path, (".usd", ".usda", ".usdc"), objects, options,
                       overwrite, context)


# ----------------------------------------------------------------------------- common

def without_collision(objects) -> list:
    """``objects`` less the collision capsules (Unreal's ``UCP_`` meshes travel in FBX only; glTF
    and USD would show them as meshes; ``collision.json`` lists them for every engine)."""
    from .lods import COLLISION_KEY
    return [ob for ob in objects if ob is not None and not ob.get(COLLISION_KEY)]


def _operator_properties(module, name: str):
    """Property identifiers of ``module.name`` → ``{identifier: rna property}``, or None if absent."""
    if name not in dir(module):
        return None
    try:
        rna = getattr(module, name).get_rna_type()
    except KeyError:
        return None
    return {p.identifier: p for p in rna.properties}


def _supported(props: dict, options: dict) -> dict:
    """``options`` this exporter knows, enum values included (e.g. 'ACTIVE_ACTIONS' from 4.0 on)."""
    out = {}
    for key, value in options.items():
        prop = props.get(key)
        if prop is None:
            continue
        if prop.type == "ENUM" and isinstance(value, str) and value not in prop.enum_items.keys():
            continue
        out[key] = value
    return out


def _export(fmt: str, module, op_name: str, path, exts: tuple, objects, options: dict, overwrite: bool,
            context, keys_from_zero: bool = False, post=None, alpha_clip: bool = False) -> str:
    context = context or bpy.context
    path = os.path.abspath(os.fspath(path))
    objects = [ob for ob in objects if ob is not None]
    if not path.lower().endswith(exts):
        raise InputError(f"'{path}' is not a {fmt} file name; use the extension {' or '.join(exts)}")
    if not objects:
        raise InputError(f"nothing to export to '{path}'; build the tree first")
    folder = os.path.dirname(path)
    if not os.path.isdir(folder):
        raise InputError(f"folder '{folder}' does not exist; create it or choose another folder")
    if os.path.exists(path) and not overwrite:
        raise InputError(f"'{path}' exists; choose another file name or allow overwriting (overwrite=True)")
    props = _operator_properties(module, op_name)
    if props is None:
        raise InputError(f"this Blender has no {fmt} exporter (operator '{op_name}' is missing); enable "
                         "its add-on in Preferences > Add-ons or export another format")
    ext = os.path.splitext(path)[1]
    tmp = os.path.join(folder, f".{os.path.basename(path)}.{uuid.uuid4().hex[:8]}.tmp{ext}")
    try:
        with played_as_action(objects), _own_scene(context, objects) as ctx, \
                _keys_from_zero(objects, keys_from_zero), \
                _frame_range(ctx.scene, objects), _baked_bark(objects), _all_rendered(objects), \
                _alpha_clipped(objects, alpha_clip):
            result = _run_operator(module, op_name, filepath=tmp, check_existing=False,
                                   **_supported(props, options))
        if "FINISHED" not in result:
            raise ExportError(f"{fmt} export to '{path}' was cancelled by the exporter ({result})")
        if not os.path.isfile(tmp):
            raise ExportError(f"{fmt} export to '{path}' wrote no file")
        if post is not None:
            post(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        _remove_quietly(tmp)
        if isinstance(exc, (InputError, ExportError)) or not isinstance(exc, Exception):
            raise
        if isinstance(exc, OSError):
            raise ExportError(f"cannot write '{path}' ({exc.strerror or exc}); check the folder's "
                              "permissions and free space") from exc
        raise ExportError(f"{fmt} export to '{path}' failed: {exc}") from exc
    return path


#: the name of the scene an export runs in when the tree has no animation (removed when it ends)
EXPORT_SCENE = ".Tree from Video export"


def animation_name(objects) -> str | None:
    """The name every export gives the tree's animation: its rig's action (``"<tree> Sway"``, or
    ``"<tree>_loop"`` for a loop, which Godot plays looped); None without an animated rig."""
    for ob in objects:
        action = rig_action(ob) if ob is not None and ob.type == "ARMATURE" else None
        if action is not None:
            return action.name
    return None


@contextmanager
def _own_scene(context, objects):
    """The export's own scene: a new scene holding only ``objects`` (linked, not copied; all
    selected, the first armature active: what the exporters' "selected only" writes) at the user's
    scene's frame rate, the context pointing at it; removed afterwards with its selection, the
    objects left where they were in the user's scene. The exporters evaluate their scene at every frame, and in the user's scene
    that is every other tree of a forest too (issue 32: one tree's glTF export 6.5 s alone, 15.6 s
    beside a 12-tree forest)."""
    src = context.scene
    missing = [ob.name for ob in objects if context.view_layer.objects.get(ob.name) is None]
    if missing:
        raise InputError(f"{', '.join(missing)} not in the current view layer; include the tree's collection")
    window = getattr(context, "window", None)
    shown = window.scene if window is not None else None
    # named after the tree's animation: FBX names its animation stack after the scene
    name = animation_name(objects)
    scene = bpy.data.scenes.new(name if name and bpy.data.scenes.get(name) is None else EXPORT_SCENE)
    try:
        scene.render.fps, scene.render.fps_base = src.render.fps, src.render.fps_base
        scene.frame_start, scene.frame_end = src.frame_start, src.frame_end
        scene.unit_settings.system = src.unit_settings.system
        scene.unit_settings.scale_length = src.unit_settings.scale_length
        for ob in objects:
            scene.collection.objects.link(ob)
        layer = scene.view_layers[0]
        for ob in objects:
            ob.select_set(True, view_layer=layer)
        layer.objects.active = next((ob for ob in objects if ob.type == "ARMATURE"), objects[0])
        # the window shows it too: the glTF exporter sets the window's scene to the context's, and
        # Blender 4.3 crashed doing that from a scene the window did not show
        if window is not None:
            window.scene = scene
        with context.temp_override(window=window, scene=scene, view_layer=layer):
            yield bpy.context
    finally:
        if window is not None and shown is not None:
            window.scene = shown
        bpy.data.scenes.remove(scene)
        src.frame_set(src.frame_current)      # the objects' poses back at the user's frame


def _run_operator(module, op_name: str, **kwargs) -> set:
    """Call the exporter operator ``module.op_name(**kwargs)`` (one seam for tests)."""
    return getattr(module, op_name)(**kwargs)


def _remove_quietly(path: str) -> None:
    try:
        os.remove(path)
    except OSError:
        pass


def safe_name(name: str) -> str:
    """``name`` as a file-name stem of ASCII letters, digits, ``_`` and ``-`` ("Tree video Leaf
    Texture" → "Tree_video_Leaf_Texture")."""
    stem = re.sub(r"[^A-Za-z0-9_-]+", "_", name).strip("_")
    return stem or "texture"


def _materials(objects) -> list:
    """The node materials of ``objects``' material slots, each once."""
    found: dict[int, bpy.types.Material] = {}
    for ob in objects:
        for slot in getattr(ob, "material_slots", ()):
            mat = slot.material
            if mat is not None and mat.node_tree is not None:
                found[mat.as_pointer()] = mat
    return list(found.values())


def _object_images(objects) -> list:
    """The images used by the materials of ``objects`` (image texture nodes), each once."""
    found: dict[int, bpy.types.Image] = {}
    for mat in _materials(objects):
        for node in mat.node_tree.nodes:
            img = getattr(node, "image", None)
            if node.type == "TEX_IMAGE" and img is not None:
                found[img.as_pointer()] = img
    return list(found.values())


def _actions(objects) -> list:
    """The actions animating ``objects`` (the rig's, the leaf mesh's shape keys'), each once."""
    out: list = []
    for ob in objects:
        for owner in (ob, getattr(getattr(ob, "data", None), "shape_keys", None)):
            ad = getattr(owner, "animation_data", None)
            if ad is not None and ad.action is not None and all(ad.action is not a for a in out):
                out.append(ad.action)
    return out


@contextmanager
def _keys_from_zero(objects, enabled: bool = True):
    """While exporting, every key and baked sample of ``objects``' actions moved so the armature's
    first key is on frame 0 (whole frames, handles too: the same curves, earlier); put back
    afterwards."""
    actions = _actions(objects) if enabled else []
    curves = [fc for a in actions for fc in action_fcurves(a) if len(fc.keyframe_points) or len(fc.sampled_points)]
    first = min((fc.range()[0] for fc in curves), default=0.0)
    shift = -float(round(first))

    def shifted(points, attrs, by: float) -> None:
        for attr in attrs:
            xy = np.empty(2 * len(points), np.float32)
            points.foreach_get(attr, xy)
            xy[0::2] += by
            points.foreach_set(attr, xy)

    def move(by: float) -> None:
        for fc in curves:
            if len(fc.keyframe_points):
                shifted(fc.keyframe_points, ("co", "handle_left", "handle_right"), by)
            if len(fc.sampled_points):
                shifted(fc.sampled_points, ("co",), by)
            fc.update()
    if shift:
        move(shift)
    try:
        yield
    finally:
        if shift:
            move(-shift)


@contextmanager
def _baked_bark(objects):
    """While exporting, every bark material of ``objects`` (marked by :func:`.materials.bark_material`)
    shows its baked images (:func:`core.detail.bark_texture.bark_textures`, packed): an albedo into
    the Principled BSDF's Base Color and a tangent-space normal map into its Normal, in place of the
    procedural nodes, which formats carrying images only drop (the bark arrived white in GLB and
    FBX). The procedural links, the nodes and the images are put back / removed afterwards."""
    from ...core.detail.bark_texture import bark_textures
    from .materials import BARK_COLOUR_KEY, BARK_KEY, BARK_PHOTO_KEY, packed_image

    def rgba(rgb):                  # uint8 (S, S, 3), row 0 at the bottom (UV v = 0) → float RGBA
        out = np.ones(rgb.shape[:2] + (4,), np.float32)
        out[..., :3] = rgb / 255.0
        return out
    done: list = []
    try:
        for mat in (m for m in _materials(objects) if BARK_KEY in m and BARK_PHOTO_KEY not in m):
            nt = mat.node_tree
            bsdf = next((n for n in nt.nodes if n.type == "BSDF_PRINCIPLED"), None)
            if bsdf is None:
                continue
            colour = mat.get(BARK_COLOUR_KEY)
            tex = bark_textures(None if colour is None else tuple(colour), str(mat[BARK_KEY]))
            entry = {"mat": mat, "nodes": [], "images": [], "links": []}
            done.append(entry)
            for socket in (bsdf.inputs["Base Color"], bsdf.inputs["Normal"]):
                entry["links"] += [(lk.from_socket, lk.to_socket) for lk in socket.links]
                for lk in list(socket.links):
                    nt.links.remove(lk)
            albedo = packed_image(safe_name(f"{mat.name} albedo"), rgba(tex.albedo), "sRGB", False)   # names USD
            normal = packed_image(safe_name(f"{mat.name} normal"), rgba(tex.normal), "Non-Color", False)  # can use
            entry["images"] += [albedo, normal]
            a_node, n_node, map_node = (nt.nodes.new(t) for t in ("ShaderNodeTexImage", "ShaderNodeTexImage",
                                                                  "ShaderNodeNormalMap"))
            entry["nodes"] += [a_node, n_node, map_node]
            a_node.image, n_node.image = albedo, normal
            nt.links.new(a_node.outputs["Color"], bsdf.inputs["Base Color"])
            nt.links.new(n_node.outputs["Color"], map_node.inputs["Color"])
            nt.links.new(map_node.outputs["Normal"], bsdf.inputs["Normal"])
        yield
    finally:
        for entry in reversed(done):
            nt = entry["mat"].node_tree
            for node in entry["nodes"]:
                nt.nodes.remove(node)
            for a, b in entry["links"]:
                nt.links.new(a, b)
            for img in entry["images"]:
                bpy.data.images.remove(img)


@contextmanager
def _alpha_clipped(objects, enabled: bool = True):
    """While exporting glTF, a Math *Round* node on the Alpha link of every alpha-tested material
    (:data:`.materials.ALPHA_CLIP_KEY`): the glTF exporter writes that as ``alphaMode`` MASK with
    cutoff 0.5 (engines sort blended foliage wrongly); the FBX exporter, which finds the alpha
    texture only on a direct link, keeps it. The links are put back afterwards."""
    from .materials import ALPHA_CLIP_KEY
    done = []
    try:
        for mat in (m for m in _materials(objects) if enabled and m.get(ALPHA_CLIP_KEY)):
            nt = mat.node_tree
            bsdf = next((n for n in nt.nodes if n.type == "BSDF_PRINCIPLED"), None)
            if bsdf is None or not bsdf.inputs["Alpha"].links:
                continue
            link = bsdf.inputs["Alpha"].links[0]
            src = link.from_socket
            nt.links.remove(link)
            node = nt.nodes.new("ShaderNodeMath")
            node.operation = "ROUND"
            nt.links.new(src, node.inputs[0])
            nt.links.new(node.outputs["Value"], bsdf.inputs["Alpha"])
            done.append((nt, node, src, bsdf))
        yield
    finally:
        for nt, node, src, bsdf in reversed(done):
            nt.nodes.remove(node)
            nt.links.new(src, bsdf.inputs["Alpha"])


@contextmanager
def _all_rendered(objects):
    """Every exported object renderable while exporting: a tree's lower LODs are hidden in renders
    (the preview shows LOD0), and the USD exporter, evaluating for render, left them out."""
    hidden = [ob for ob in objects if ob.hide_render]
    for ob in hidden:
        ob.hide_render = False
    try:
        yield
    finally:
        for ob in hidden:
            try:
                ob.hide_render = True
            except ReferenceError:
                pass


@contextmanager
def _safe_image_names(objects):
    """Give the images of ``objects`` safe names while exporting (the USD exporter names the
    texture files after them); put the old names back afterwards."""
    renamed = []
    try:
        for img in _object_images(objects):
            new = safe_name(img.name)
            if new != img.name:
                renamed.append((img, img.name))
                img.name = new
        yield
    finally:
        for img, old in reversed(renamed):
            try:
                img.name = old
            except ReferenceError:
                pass


@contextmanager
def _frame_range(scene, objects):
    """Set the scene's frame range to the armature action's keys (if any) while exporting."""
    old = scene.frame_start, scene.frame_end, scene.frame_current
    rng = None
    for ob in objects:
        ad = ob.animation_data
        if ob.type == "ARMATURE" and ad is not None and ad.action is not None:
            ranges = [fc.range() for fc in action_fcurves(ad.action)]
            if ranges:          # Action.frame_range turns one keyed frame into two
                rng = (int(round(min(r[0] for r in ranges))), int(round(max(r[1] for r in ranges))))
                break
    try:
        if rng is not None:
            set_frame_range(scene, *rng)
        yield
    finally:
        set_frame_range(scene, old[0], old[1])
        scene.frame_set(old[2])
