"""The impostor and the billboard rendered in Blender (issue 33, ``--impostor``; issue 36,
``--billboard``; their layouts are the core's, :mod:`core.asset.impostor` and
:mod:`core.asset.billboard`): every cell of the hemi-octahedral atlas, or the billboard's front
view, a Workbench render of the tree at rest — albedo (the materials' texture colours, flat light,
alpha the coverage) and normals (each vertex's rest normal in glTF axes as a colour attribute, raw
view transform) — and the crossed-billboard card mesh ``<tree>_LOD<k>`` that shows two of the
atlas's cells, the last level of detail.

Rendered in a scene of its own (:class:`ViewRenderer`: the tree's objects linked, the armature in
its rest position), so the user's scene, frame and render settings are untouched.
"""
from __future__ import annotations

import os
import tempfile

import bpy
import numpy as np
from mathutils import Matrix

from ...core.asset.axes import TO_GLTF
from ...core.asset.impostor import ImpostorLayout, card_mesh, grid_directions, view_basis
from .objects import Created, new_mesh

NORMAL_ATTR = "ImpostorNormal"


def _render(scene, path: str) -> np.ndarray:
    import cv2
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True, scene=scene.name)
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None or img.ndim != 3 or img.shape[2] != 4:
        raise RuntimeError(f"the impostor render '{path}' could not be read back")
    return img[..., [2, 1, 0, 3]]


def box_down(img: np.ndarray, k: int) -> np.ndarray:
    """``(H, W, 4)`` uint8 RGBA of a render ``(k·H, k·W, 4)`` made without anti-aliasing: alpha the
    share of each pixel's ``k × k`` samples covered (a box filter: the coverage itself), colour the
    covered samples' mean (alpha-weighted)."""
    H, W = img.shape[0] // k, img.shape[1] // k
    x = img[:H * k, :W * k].astype(np.float64).reshape(H, k, W, k, 4)
    a = x[..., 3] / 255.0
    cover = a.sum(axis=(1, 3))
    rgb = (x[..., :3] * a[..., None]).sum(axis=(1, 3)) / np.maximum(cover, 1e-9)[..., None]
    out = np.concatenate([rgb, (cover / (k * k) * 255.0)[..., None]], axis=-1)
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


class ViewRenderer:
    """Renders ``meshes`` on ``rig`` at rest in a scene of its own (the user's scene, frame and
    render settings untouched): :meth:`render` gives a view's albedo (the materials' texture
    colours, flat light, alpha the coverage) and normals (each vertex's rest normal in glTF axes as
    a colour attribute, raw view transform). A context manager: on leaving, the scene, the camera,
    the attributes and the temporary files are gone and the rig's pose is as it was."""

    def __init__(self, rig, meshes):
        self.rig, self.meshes = rig, list(meshes)

    def __enter__(self) -> "ViewRenderer":
        self.scene = scene = bpy.data.scenes.new(".Tree from Video views")
        self.cam = cam = bpy.data.objects.new(".views camera", bpy.data.cameras.new(".views camera"))
        self.folder = tempfile.mkdtemp(prefix="tree_video_views_")
        self.old_pose = self.rig.data.pose_position
        self.added: list = []
        try:
            for ob in [self.rig, *self.meshes]:
                scene.collection.objects.link(ob)
            scene.collection.objects.link(cam)
            scene.camera = cam
            cam.data.type = "ORTHO"
            r = scene.render
            r.engine = "BLENDER_WORKBENCH"
            r.film_transparent = True
            r.resolution_percentage = 100
            r.image_settings.file_format = "PNG"
            r.image_settings.color_mode = "RGBA"
            r.image_settings.color_depth = "8"
            scene.display.shading.light = "FLAT"
            self.rig.data.pose_position = "REST"
            for ob in self.meshes:                        # rest normals in glTF axes, as colours
                me = ob.data
                n = np.empty(3 * len(me.vertices), np.float32)
                me.vertices.foreach_get("normal", n)
                attr = me.color_attributes.new(NORMAL_ATTR, "FLOAT_COLOR", "POINT")
                self.added.append((me, attr.name, me.color_attributes.active_color_name))
                col = np.ones((len(me.vertices), 4), np.float32)
                col[:, :3] = 0.5 * (n.reshape(-1, 3) @ TO_GLTF.T + 1.0)
                attr.data.foreach_set("color", col.ravel())
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def render(self, centre, forward, right, up, ortho_scale: float, res: tuple[int, int],
               depth: float, supersample: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """``(albedo, normal)`` ``(H, W, 4)`` uint8 RGBA (row 0 the top) of the orthographic view
        through ``centre`` looking along ``forward`` (Blender axes, unit ``right``/``up``),
        ``ortho_scale`` metres across the longer side of ``res = (W, H)`` px, the camera ``depth``
        metres back. ``supersample`` k > 1: the albedo rendered k× as fine without anti-aliasing
        and box-filtered (:func:`box_down`), so its alpha is each pixel's coverage in every Blender
        (4.3's Workbench anti-aliasing left a fully covered one-pixel twig at alpha ~0.4)."""
        scene, cam = self.scene, self.cam
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2] = right, up, -np.asarray(forward)   # a camera looks down its -Z
        m[:3, 3] = np.asarray(centre) - np.asarray(forward) * depth
        cam.matrix_world = Matrix(m.tolist())
        cam.data.ortho_scale = float(ortho_scale)
        cam.data.clip_start, cam.data.clip_end = 0.001, 2.0 * depth + 1.0
        scene.render.resolution_x, scene.render.resolution_y = int(res[0]), int(res[1])
        scene.display.shading.color_type = "TEXTURE"
        scene.view_settings.view_transform = "Standard"
        k = max(int(supersample), 1)
        if k > 1:
            scene.render.resolution_x, scene.render.resolution_y = int(res[0]) * k, int(res[1]) * k
            scene.display.render_aa = "OFF"
            a = box_down(_render(scene, os.path.join(self.folder, "a.png")), k)
            scene.render.resolution_x, scene.render.resolution_y = int(res[0]), int(res[1])
        else:
            scene.display.render_aa = "8"
            a = _render(scene, os.path.join(self.folder, "a.png"))
        for me, name, _ in self.added:
            me.color_attributes.active_color_name = name
        scene.display.shading.color_type = "VERTEX"
        scene.view_settings.view_transform = "Raw"           # the attribute's values as they are
        scene.display.render_aa = "OFF"                      # one surface a pixel: no averaged normals
        nrm = _render(scene, os.path.join(self.folder, "n.png"))
        v = nrm[..., :3].astype(np.float64) / 255.0 * 2.0 - 1.0
        v /= np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-6)
        nrm[..., :3] = np.round((v + 1.0) / 2.0 * 255.0).astype(np.uint8)
        nrm[..., 3] = a[..., 3]                   # the albedo's cut-out leaves are the coverage
        nrm[a[..., 3] == 0, :3] = 128
        return a, nrm

    def __exit__(self, *exc) -> None:
        self.rig.data.pose_position = self.old_pose
        for me, name, active in self.added:
            attr = me.color_attributes.get(name)
            if attr is not None:
                me.color_attributes.remove(attr)
            if active and me.color_attributes.get(active) is not None:
                me.color_attributes.active_color_name = active
        bpy.data.scenes.remove(self.scene)
        cam_data = self.cam.data
        bpy.data.objects.remove(self.cam)
        bpy.data.cameras.remove(cam_data)
        for f in os.listdir(self.folder):
            os.unlink(os.path.join(self.folder, f))
        os.rmdir(self.folder)


def render_atlas(rig, meshes, layout: ImpostorLayout) -> tuple[np.ndarray, np.ndarray]:
    """``(albedo, normal)`` atlases ``(S, S, 4)`` uint8 RGBA (row 0 the top) of ``meshes`` (the
    tree's LOD0 objects) on ``rig`` at rest."""
    dirs = grid_directions(layout.grid)
    S, c = layout.cell, layout.grid
    albedo = np.zeros((layout.size, layout.size, 4), np.uint8)
    normal = np.zeros_like(albedo)
    with ViewRenderer(rig, meshes) as views:
        for j in range(c):
            for i in range(c):
                forward, right, up = view_basis(dirs[j, i])
                a, nrm = views.render(layout.centre, forward, right, up, 2.0 * layout.radius, (S, S),
                                      4.0 * layout.radius)
                albedo[j * S:(j + 1) * S, i * S:(i + 1) * S] = a
                normal[j * S:(j + 1) * S, i * S:(i + 1) * S] = nrm
    return albedo, normal


#: the billboard's albedo is rendered this many times as fine and box-filtered (:meth:`ViewRenderer.render`)
BILLBOARD_SUPERSAMPLE = 4


def render_billboard(rig, meshes, view) -> tuple[np.ndarray, np.ndarray]:
    """``(albedo, normal)`` ``(H, W, 4)`` uint8 RGBA of the tree's front at rest, framed as
    ``view`` (:class:`core.asset.billboard.BillboardView`)."""
    with ViewRenderer(rig, meshes) as views:
        return views.render(view.centre, view.forward, view.right, view.up, view.ortho_scale, view.px,
                            view.depth, supersample=BILLBOARD_SUPERSAMPLE)


def build_card(layout: ImpostorLayout, albedo: np.ndarray, rig, root_bone: str, coll, name: str, parent,
               created: Created):
    """The crossed-billboard object ``name`` (two quads, :func:`core.asset.impostor.card_mesh`) with
    a material showing the atlas (packed, alpha-tested), skinned to ``root_bone`` of ``rig``."""
    from .materials import ALPHA_CLIP_KEY, packed_image, principled_nodes
    co, uv, quads = card_mesh(layout, float(rig.data.bones[root_bone].head_local[2]))
    me = new_mesh(name, co, quads.ravel(), np.full(len(quads), 4), created)
    me.uv_layers.new(name="UVMap").data.foreach_set("uv", uv[quads.ravel()].ravel())
    rgba = albedo[::-1].astype(np.float32) / 255.0          # Blender's image rows run bottom-up
    img = created.add(bpy.data.images, packed_image(f"{name} atlas", rgba, "sRGB", True))
    mat = created.add(bpy.data.materials, bpy.data.materials.new(f"{name} Impostor"))
    nt, out, bsdf = principled_nodes(mat)
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    mat[ALPHA_CLIP_KEY] = True                                # alpha-tested (glTF MASK)
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    mat.use_backface_culling = False
    me.materials.append(mat)
    ob = created.add(bpy.data.objects, bpy.data.objects.new(name, me))
    coll.objects.link(ob)
    ob.vertex_groups.new(name=root_bone).add(list(range(len(co))), 1.0, "REPLACE")
    mod = ob.modifiers.new("Armature", "ARMATURE")
    mod.object = rig
    ob.parent = parent
    ob.hide_render = True
    return ob


def impostor_files(layout: ImpostorLayout, albedo: np.ndarray, normal: np.ndarray, tree_name: str) -> dict[str, bytes]:
    """``impostor_albedo.png``, ``impostor_normal.png`` and ``impostor.json`` as bytes."""
    import cv2

    from ...core.asset.impostor import FILES, impostor_doc
    from ...core.fileio import json_bytes
    out = {}
    for name, img in zip(FILES[:2], (albedo, normal)):
        ok, png = cv2.imencode(".png", img[..., [2, 1, 0, 3]])
        if not ok:
            raise RuntimeError(f"OpenCV could not encode {name}")
        out[name] = png.tobytes()
    out[FILES[2]] = json_bytes(impostor_doc(layout, tree_name))
    return out
