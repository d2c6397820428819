"""Everything the batch job writes from a :class:`Tree3D`: the scene (armature + branch mesh),
FBX / USD / glTF, a .blend, and a preview image (front and side views, Workbench).

Every file is written to a temporary name in its folder and renamed when complete; an existing
file is replaced only with ``overwrite``.
"""
from __future__ import annotations

import os
import tempfile

import bpy
import numpy as np

from ...core.asset.billboard import FILES as BILLBOARD_FILES
from ...core.asset.billboard import billboard_files, billboard_view
from ...core.asset.engine_files import engine_line
from ...core.asset.game import GameSettings, fbx_options
from ...core.asset.web_viewer import check_viewer_sources, write_viewer
from ...core.errors import InputError
from ...core.fileio import publish, temp_path, write_files
from ...core.formats import FORMATS, by_flag
from ...core.loop import maybe_loop
from ...core.tree3d import Tree3D
from . import export, trees
from .build import build_tree
from .game import build_kwargs, built_engine_files
from .impostor import render_billboard


def wanted_files(out_dir: str, wanted: dict) -> list[str]:
    """Paths the job will write for ``wanted`` = {format flag: bool} (:mod:`core.formats`)."""
    return [os.path.join(out_dir, by_flag(k).file) for k, on in wanted.items() if on]


def check_wanted(wanted: dict) -> None:
    """Refuse, before any work, what this Blender cannot write."""
    if any(wanted.get(f.flag) and f.needs_usd for f in FORMATS) and not export.has_usd():
        raise InputError("this Blender was built without USD (e.g. Debian's); drop --usd or use FBX/glTF")


def write_outputs(tree: Tree3D, out_dir: str, wanted: dict, overwrite: bool = False,
                  fresh_scene: bool = True, report=print, leaf_image: str | None = None,
                  loop_s: float = 0.0, game: GameSettings | None = None, stats: dict | None = None,
                  bark_maps=None, billboard_px: int = 0) -> dict:
    """Build ``tree`` in the scene and write the ``wanted`` files into ``out_dir``.

    ``wanted`` = {format flag: bool} (:mod:`core.formats`); ``fresh_scene`` starts from an empty
    scene (batch runs); ``loop_s`` > 0 cuts the motion to a seamless loop of about that many
    seconds first (:func:`core.loop.loop_tree`); ``game`` the game export's bone budget, levels of
    detail and engine files (:class:`core.asset.game.GameSettings`); returns {format flag: path}.
    ``stats`` (a job's counts) gets the built rig's bones and the first level's triangles added.
    ``bark_maps``: the bark from photos of bark (:mod:`core.detail.bark_photo`; None: procedural).
    ``billboard_px`` > 0: the tree's front at rest rendered with that many pixels on its longer side
    (:mod:`core.asset.billboard`: ``billboard.png``, ``billboard_normal.png``, ``billboard.json``).
    """
    check_wanted(wanted)
    game = game or GameSettings()
    if game.viewer:
        check_viewer_sources()
        if not wanted.get("gltf"):
            raise InputError("--viewer plays tree.glb; add --gltf")
    extra_files = list(game.files()) + (list(BILLBOARD_FILES) if billboard_px else [])
    for path in wanted_files(out_dir, wanted) + [os.path.join(out_dir, f) for f in extra_files]:
        if os.path.exists(path) and not overwrite:
            raise InputError(f"{path} exists; pass --force to overwrite or choose another --out")
    tree, note = maybe_loop(tree, loop_s)
    if note:
        report(f"[loop] {note}")
    if fresh_scene:
        bpy.ops.wm.read_factory_settings(use_empty=True)
    context = bpy.context
    built = build_tree(context, tree, tree.name, replace=True, leaf_image=leaf_image, bark_maps=bark_maps,
                       **build_kwargs(game))
    if built["budget"] is not None:
        report(f"[bones] {built['budget'].line()}")
    if built["lods"]:
        report(f"[lods] {lod_line(built['lods'])}")
    objects = trees.tree_objects(built["collection"])
    if stats is not None:
        for k, v in built["asset"].counts().items():
            stats[k] = int(stats.get(k, 0)) + v
    written = {}
    for f in FORMATS:                       # the interchange files, in the registry's order
        if f.interchange and wanted.get(f.flag):
            extra = {"extra": fbx_options(game.engine)} if f.flag == "fbx" else {}
            if f.flag == "gltf" and game.is_game:
                extra = {"game": True}
            written[f.flag] = getattr(export, f.writer)(os.path.join(out_dir, f.file), objects, overwrite=overwrite,
                                                        **extra)
            report(f"[export] {written[f.flag]}")
    asset = built["asset"]
    files = built_engine_files(built, tree, game)
    if files:
        written["engine"] = write_files(out_dir, files)
        report(f"[engine files] {engine_line(asset, game)}: {', '.join(files)}")
    if billboard_px:
        written["billboard"] = write_files(out_dir, billboard(built, tree.name, billboard_px))
        report(f"[billboard] {written['billboard'][0]} ({billboard_px} px on its longer side)")
    if game.viewer:
        written["viewer"] = write_viewer(out_dir)
        report(f"[viewer] {written['viewer']} (open it through a local server: python -m http.server)")
    if wanted.get("preview"):
        written["preview"] = render_preview(context, tree, objects, os.path.join(out_dir, by_flag("preview").file))
        report(f"[preview] {written['preview']}")
    if wanted.get("blend"):
        written["blend"] = save_blend(os.path.join(out_dir, by_flag("blend").file))
        report(f"[blend] {written['blend']}")
    return written


def billboard(built: dict, tree_name: str, px: int) -> dict[str, bytes]:
    """The billboard files of a tree ``build_tree`` made (``built``): :func:`billboard_meshes`
    rendered at rest from the front, framed on their rest points."""
    meshes = billboard_meshes(built["collection"])
    return billboard_render(built["armature"], meshes, rest_points(meshes), tree_name, px)


def billboard_meshes(coll) -> list:
    """What a tree's billboard shows: its first level of detail, else its branch and leaf meshes."""
    meshes = [ob for ob in coll.all_objects if ob.type == "MESH"]
    lod0 = [ob for ob in meshes if ob.name.endswith("_LOD0")]
    return lod0 or [ob for ob in meshes if ob.name in (f"{coll.name} Branches", f"{coll.name} Leaves")]


def rest_points(meshes) -> np.ndarray:
    """``(P, 3)`` world metres of the meshes' vertices at rest (their data, not the posed shape)."""
    out = []
    for ob in meshes:
        co = np.empty(len(ob.data.vertices) * 3, np.float32)
        ob.data.vertices.foreach_get("co", co)
        mw = np.array(ob.matrix_world, np.float64)
        out.append(co.reshape(-1, 3).astype(np.float64) @ mw[:3, :3].T + mw[:3, 3])
    return np.concatenate(out)


def billboard_render(rig, meshes, points: np.ndarray, tree_name: str, px: int) -> dict[str, bytes]:
    """The billboard files of ``meshes`` on ``rig`` at rest, framed on their rest ``points (P, 3)``
    (world metres), ``px`` pixels on the longer side (:mod:`core.asset.billboard`); the json says
    where the rig's origin (the tree's base) lands."""
    view = billboard_view(points, px)
    albedo, normal = render_billboard(rig, meshes, view)
    return billboard_files(view, albedo, normal, tree_name, np.asarray(rig.matrix_world.translation, np.float64))


def lod_line(objs) -> str:
    """``"LOD0 45,940 triangles, LOD1 17,724 (39 %), …"`` of the level objects ``objs``."""
    tris = []
    for ob in objs:
        me = ob.data
        me.calc_loop_triangles()
        tris.append(len(me.loop_triangles))
    parts = [f"{ob.name.rsplit('_', 1)[-1]} {t:,} triangles" + (f" ({100 * t / max(tris[0], 1):.0f} %)" if k else "")
             for k, (ob, t) in enumerate(zip(objs, tris))]
    return ", ".join(parts)


def save_blend(path: str) -> str:
    """Save a copy of the current file to ``path`` atomically (the session's file name is kept)."""
    tmp = temp_path(path, ".blend")          # must not exist: Blender would back it up as .blend1
    try:
        bpy.ops.wm.save_as_mainfile(filepath=tmp, copy=True, compress=True)
        publish(tmp, path)
    finally:
        for leftover in (tmp, tmp + "1"):
            if os.path.exists(leftover):
                os.unlink(leftover)
    return path


def _camera(scene, name: str, location, rotation, ortho_scale: float):
    cam_data = bpy.data.cameras.new(name)
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = ortho_scale
    cam_data.clip_end = 10 * ortho_scale + 100
    cam = bpy.data.objects.new(name, cam_data)
    cam.location = location
    cam.rotation_euler = rotation
    scene.collection.objects.link(cam)
    return cam


def render_preview(context, tree: Tree3D, objects, path: str, size: tuple[int, int] = (480, 540)) -> str:
    """Front and side orthographic Workbench renders of frame 1, side by side, to ``path`` (PNG).

    Temporary cameras and render settings are removed/restored afterwards."""
    import cv2

    scene = context.scene
    pts = tree.nodes3d[0]
    lo, hi = pts.min(0), pts.max(0)
    centre = 0.5 * (lo + hi)
    extent = float(max(hi[2] - lo[2], hi[0] - lo[0], hi[1] - lo[1])) * 1.15 + 1e-3
    dist = 4 * extent
    r = scene.render
    saved = (r.engine, r.resolution_x, r.resolution_y, r.resolution_percentage, r.filepath,
             r.image_settings.file_format, scene.camera, scene.frame_current)
    cams = []
    folder = os.path.dirname(os.path.abspath(path))
    tmp_files = []
    try:
        r.engine = "BLENDER_WORKBENCH"
        r.resolution_x, r.resolution_y, r.resolution_percentage = size[0], size[1], 100
        r.image_settings.file_format = "PNG"
        shading = scene.display.shading
        shading.light = "STUDIO"
        shading.color_type = "TEXTURE"        # bark colour, leaf cards cut out by their image
        world = scene.world or bpy.data.worlds.new("Preview World")
        scene.world = world
        world.color = (0.85, 0.9, 0.95)
        scene.frame_set(1)
        views = (("front", (centre[0], lo[1] - dist, centre[2]), (np.pi / 2, 0.0, 0.0)),
                 ("side", (hi[0] + dist, centre[1], centre[2]), (np.pi / 2, 0.0, np.pi / 2)))
        images = []
        for name, loc, rot in views:
            cam = _camera(scene, f"Preview {name}", loc, rot, extent)
            cams.append(cam)
            scene.camera = cam
            fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".png", dir=folder)
            os.close(fd)
            tmp_files.append(tmp)
            r.filepath = tmp
            bpy.ops.render.render(write_still=True)
            img = cv2.imread(tmp)
            cv2.putText(img, name, (12, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.8, (40, 40, 40), 2, cv2.LINE_AA)
            images.append(img)
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".png", dir=folder)
        os.close(fd)
        tmp_files.append(tmp)
        cv2.imwrite(tmp, np.hstack(images))
        publish(tmp, path)
    finally:
        for cam in cams:
            data = cam.data
            bpy.data.objects.remove(cam)
            bpy.data.cameras.remove(data)
        (r.engine, r.resolution_x, r.resolution_y, r.resolution_percentage, r.filepath,
         r.image_settings.file_format, scene.camera, frame) = saved
        scene.frame_set(frame)
        for f in tmp_files:
            if os.path.exists(f):
                os.unlink(f)
    return path
