"""Build an animated :class:`Tree3D` in the scene: a keyed armature (:mod:`.armature`), a skinned
branch mesh (:mod:`.branch_mesh`), leaf bones and cards (:mod:`.leaves`) and their materials
(:mod:`.materials`), in a collection of their own.

:func:`build_tree` is all-or-nothing: if any step fails, every object and data-block it created
is removed (:class:`.objects.Created`) and the error re-raised. Frame ``t`` of the tree (0-based)
is scene frame ``t + 1``.
"""
from __future__ import annotations

import math
import time

import bpy
import numpy as np

from ...core import bones
from ...core.asset import impostor as imp_core
from ...core.asset import tree_asset
from ...core.errors import InputError
from ...core.tree3d import Tree3D, last_key_frame
from . import armature, branch_mesh, objects, timing, trees
from . import impostor as imp_build
from . import leaves as leaf_build  # build_tree has the parameters "leaves" and "materials"
from . import lods as lod_build
from . import materials as mats
from .objects import Created, deselect_all

#: Blender's longest ID name (bytes).
MAX_NAME = 63


def build_tree(context, tree: Tree3D, collection_name: str, *, replace: bool = False,
               mesh: bool = True, sides: int = 8, leaves: bool = True,
               leaf_image: str | None = None, curliness: float | None = None,
               bark: str | None = None, forks: str | None = None, relief_cm: float | None = None,
               materials: dict | None = None, update_frame: bool = True,
               keep_view: bool = False, every_key: bool = False, bone_budget: int | None = None,
               lods: int = 1, pivots: bool = False, collision: bool = False, impostor: bool = False,
               bark_maps=None) -> dict:
    """Create the animated tree in a new collection ``collection_name`` under the scene collection
    (unselected, its rig active, at the scene's first frame; with ``keep_view`` the selection, the
    active object and the current frame stay as they were: a tree generated into a scene).

    Creates an armature object ``"<name> Rig"`` (one bone per edge, ``"B{child:03d}"``, rest pose =
    tree frame 0, roll 0, connected to the parent bone; the bones in a hidden bone collection
    ``"Branches"``, so the viewport draws no sticks) whose pose bones are keyed in QUATERNION
    mode on the scene frames ``1..F`` where the motion needs a key (action ``"<name> Sway"``, or
    ``"<name>_loop"`` for a loop, :func:`core.loop.loop_tree`:
    :func:`core.keys.tree_keys`, Bezier keys or baked samples, no node more than ``KEY_TOLERANCE``
    of the height off the full motion at any frame; ``every_key``: a LINEAR key on every frame); the first tree of
    a scene sets its fps (``fps`` int + ``fps_base``) and frame range ``1..F``, a later one only
    grows the range to cover ``1..F`` (:func:`.timing.fit_scene_timing`); with ``mesh``, a branch mesh
    ``"<name> Branches"`` (tapered tubes with ``sides`` sides, one vertex group per bone, Armature
    modifier, parented to the rig; ``curliness`` 0..1 and ``bark`` "none"/"smooth"/"rough" as in
    :mod:`core.branch_mesh`, ``forks`` "joined"/"overlap" and ``relief_cm`` the bark's relief as
    geometry, None: from ``tree.meta["mesh"]``, see :func:`mesh_params`; the relief follows
    ``bark_maps``' height when given, its tiles as many as the bark material's) and a bark
    material ``"<name> Bark"``; with ``leaves`` and
    ``tree.leaves``, one bone per leaf cluster (``"L0000"``…, child of its branch bone, keyed with
    its flutter) and a skinned leaf mesh ``"<name> Leaves"`` with material ``"<name> Leaf"``
    (the leaf image ``leaf_image``, packed, or a procedural leaf).

    An existing collection of that name raises :class:`InputError` unless ``replace``; then its
    objects and their data are removed once the new tree is complete (a failed build leaves the
    old tree as it was).

    ``materials`` ``{"bark": Material, "leaf": Material}`` reuses existing materials (a forest
    shares one bark and one leaf material) instead of creating them. ``update_frame=False`` skips
    evaluating the scene at its first frame at the end (a forest does it once after all trees).

    The new objects land unselected, the rig active. ``bone_budget``: a game rig of at most that
    many bones, the motion re-fitted (:mod:`core.asset.budget`; no leaf bones, each kept bone keyed
    on every frame in rotation and location); its report is returned as ``"budget"``. ``lods`` ≥ 2:
    instead of the branch and leaf meshes, one mesh per level of detail ``"<name>_LOD0"``… (branches
    and leaves joined, :mod:`.lods`), returned as ``"lods"``; ``"mesh"`` is LOD0 then. ``pivots``:
    every mesh gets a second UV map ``"PivotPainter"``, each vertex at its Pivot Painter 2 element's
    pixel (:mod:`core.asset.pivot_painter`). ``collision``: capsule meshes ``UCP_<name>_NN`` for the
    trunk and main limbs (:mod:`core.asset.collision`; Unreal's FBX names; shown as wire, not
    rendered, written to FBX only), returned as ``"collision"``. ``impostor``: the hemi-octahedral
    atlas rendered from LOD0 at rest (:mod:`.impostor`) and a crossed-billboard card as the last
    level ``"<name>_LOD<k>"`` (LOD objects are built even for one level); its files' bytes
    returned as ``"impostor"`` ({} without). The core's :class:`core.asset.TreeAsset` is returned
    as ``"asset"`` (what the engine files are written from). ``bark_maps`` (a
    :class:`core.detail.bark_photo.BarkMaps`): the bark from photos of bark instead of the
    procedural one (:func:`.materials.photo_bark_material`).

    Returns ``{"collection", "armature", "mesh" (or None), "action", "keys" (the kept keys,
    :class:`core.keys.TreeKeys`, or None with ``every_key``), "material" (or None), "leaves" (or
    None), "leaf_polygons", "timings"}`` with ``timings`` in seconds (``rig arrays``, ``mesh arrays``,
    ``leaf arrays``: the core's :func:`core.asset.tree_asset`; ``armature``, ``keys``, ``mesh``,
    ``leaves``: the copies into Blender; ``total``)."""
    t_total = time.perf_counter()
    _validate(tree, collection_name, sides)
    layer = context.view_layer                  # what keep_view restores (edit mode needs the rig active)
    was_selected = [o for o in layer.objects if o.select_get()] if keep_view else []
    was_active = layer.objects.active
    old = bpy.data.collections.get(collection_name)
    if old is not None and not replace:
        raise InputError(f"a collection named '{collection_name}' already exists; choose another name "
                         "or replace it (replace=True)")
    # everything Blender copies, computed in the core (rig, keys, meshes, look)
    relief_map = None
    if bark_maps is not None:          # the photo's height, as many tiles round the tube as its material has
        from ...core.detail.bark_photo import uv_repeats
        shared = (materials or {}).get("bark")
        repeats = shared.get(mats.BARK_PHOTO_KEY) if shared is not None else None
        relief_map = (bark_maps.textures.height,
                      int(repeats) if repeats else uv_repeats(float(tree.radius[0]), bark_maps.scale_cm))
    asset = tree_asset(tree, mesh=mesh, leaves=leaves, sides=sides, curliness=curliness, bark=bark, forks=forks,
                       relief_cm=relief_cm, relief_map=relief_map, leaf_image=leaf_image,
                       every_key=every_key, bone_budget=bone_budget, lods=lods,
                       pivots=pivots, collision=collision,
                       as_levels=impostor)
    timings = dict(asset.timings)
    # a loop's action is named so engines loop it (Godot loops an animation whose name ends in "loop")
    action_name = f"{collection_name}_loop" if tree.meta.get("loop") else f"{collection_name} Sway"
    names = {"rig": f"{collection_name} Rig", "action": action_name,
             "mesh": f"{collection_name} Branches", "material": f"{collection_name} Bark",
             "leaves": f"{collection_name} Leaves", "leaf_material": f"{collection_name} Leaf"}
    rig_data, look = asset.rig, asset.look
    created = Created()
    try:
        scene = context.scene
        if context.mode != "OBJECT" and context.active_object is not None:
            bpy.ops.object.mode_set(mode="OBJECT")
        coll = created.add(bpy.data.collections, bpy.data.collections.new(collection_name))
        trees.mark(coll)                  # Export and the tree lists find it by this mark
        scene.collection.children.link(coll)

        t = time.perf_counter()
        rig = armature.build_armature(context, rig_data, coll, names["rig"], created)
        timings["armature"] = time.perf_counter() - t
        offset = tree.meta.get("shot_offset_m")      # one of several trees of a shot: where it stands
        if offset is not None:
            rig.location = tuple(float(v) for v in offset)

        t = time.perf_counter()
        branch_names = rig_data.names[:rig_data.n_branch]
        action, make_fcurve = armature.key_pose(rig, rig_data.keys, branch_names, names["action"], created)
        if rig_data.leaf_keys is not None:
            leaf_build.key_leaf_bones(make_fcurve, rig_data.leaf_keys, rig_data.leaf_names)
        timings["keys"] = time.perf_counter() - t
        render = scene.render
        saved = (render.fps, render.fps_base, scene.frame_start, scene.frame_end, scene.frame_current)
        created.on_failure(lambda: timing.restore_scene_timing(scene, *saved))
        timing.fit_scene_timing(scene, tree.fps, last_key_frame(tree), first=not trees.scene_trees(scene, exclude=coll))

        mesh_obj = material = leaf_obj = leaf_mat = None
        root = int(np.flatnonzero(rig_data.parent < 0)[0])       # the root bone (a card, its PP2 element)
        lod_objs: list = []
        impostor_files: dict = {}
        t = time.perf_counter()
        if asset.branches is not None:
            material = (materials or {}).get("bark")
            if material is None and bark_maps is not None:      # bark from photos of bark
                from ...core.detail.bark_photo import uv_square
                albedo, normal, rough, repeats = uv_square(bark_maps, float(tree.radius[0]))
                material = created.add(bpy.data.materials, mats.photo_bark_material(
                    names["material"], albedo, normal, rough, repeats))
                for img in mats.material_images(material):
                    created.add(bpy.data.images, img)
            if material is None:
                material = created.add(bpy.data.materials, mats.bark_material(
                    names["material"], look.mesh.bark, look.bark_colour))
        if asset.leaves is not None:
            leaf_mat = (materials or {}).get("leaf")
            if leaf_mat is None:
                leaf_mat = created.add(bpy.data.materials, mats.leaf_material(
                    names["leaf_material"], leaf_image, look.leaf_tint, look.leaf_colour,
                    tree.leaves.shape if tree.leaves is not None else "cluster"))
                for img in mats.material_images(leaf_mat):
                    created.add(bpy.data.images, img)
        timings["materials"] = time.perf_counter() - t
        if asset.lods:                          # game levels of detail: one joined mesh per level
            t = time.perf_counter()
            lod_objs = [lod_build.build_lod(lv, k, rig_data.names, rig, coll, collection_name, material, leaf_mat,
                                            created) for k, lv in enumerate(asset.lods)]
            mesh_obj = lod_objs[0]
            group = lod_build.lod_group(rig, coll, collection_name, lod_objs, created)
            timings["lods"] = time.perf_counter() - t
            if impostor:
                t = time.perf_counter()
                pts = np.concatenate([m.co for m in (asset.lods[0].branches, asset.lods[0].leaves) if m is not None])
                layout = imp_core.layout_for(pts)
                albedo, normal = imp_build.render_atlas(rig, [lod_objs[0]], layout)
                card = imp_build.build_card(layout, albedo, rig, rig_data.names[root], coll,
                                            lod_build.lod_name(collection_name, len(lod_objs)), group, created)
                lod_objs.append(card)
                impostor_files = imp_build.impostor_files(layout, albedo, normal, collection_name)
                timings["impostor"] = time.perf_counter() - t
        else:
            if asset.branches is not None:
                t = time.perf_counter()
                mesh_obj = branch_mesh.build_mesh(asset.branches, rig_data.names, rig, coll, names["mesh"],
                                                  material, created)
                timings["mesh"] = time.perf_counter() - t
            if asset.leaves is not None:
                t = time.perf_counter()
                leaf_obj = leaf_build.build_leaf_mesh(asset.leaves, rig, coll, names["leaves"], rig_data.names,
                                                      leaf_mat, created)
                timings["leaves"] = time.perf_counter() - t

        if asset.pivots is not None:            # PP2: each vertex's element in UV channel 1
            pp = asset.pivots
            meshes = [(ob, np.concatenate([m.bone for m in (lv.branches, lv.leaves) if m is not None]))
                      for ob, lv in zip(lod_objs, asset.lods)]
            meshes += [(ob, m.bone) for ob, m in ((mesh_obj, asset.branches), (leaf_obj, asset.leaves))
                       if ob is not None and not lod_objs and m is not None]
            meshes += [(ob, np.full(len(ob.data.vertices), root)) for ob in lod_objs[len(asset.lods):]]   # the card
            for ob, bone in meshes:
                objects.add_vertex_uv(ob, "PivotPainter", pp.uv(bone))

        caps = [lod_build.build_capsule(c, k, rig, coll, collection_name, created) for k, c in enumerate(asset.capsules)]

        if old is not None:
            objects.remove_collection(old)
            for k, ob in enumerate(lod_objs):
                for id_ in (ob, ob.data):
                    if id_.name != lod_build.lod_name(collection_name, k):
                        id_.name = lod_build.lod_name(collection_name, k)
            for id_, name in ((coll, collection_name), (rig, names["rig"]), (rig.data, names["rig"]),
                              (action, names["action"]), (mesh_obj, names["mesh"]),
                              (mesh_obj and mesh_obj.data, names["mesh"]), (material, names["material"]),
                              (leaf_obj, names["leaves"]), (leaf_obj and leaf_obj.data, names["leaves"]),
                              (leaf_mat, names["leaf_material"])):
                shared = materials is not None and any(id_ is m for m in materials.values())
                if id_ is not None and id_.name != name and not shared:
                    id_.name = name
        if keep_view:                           # generated into the artist's scene: their frame and selection
            deselect_all(layer)
            for ob in was_selected:
                try:
                    ob.select_set(True)
                except (ReferenceError, RuntimeError):    # removed meanwhile (a replaced tree's)
                    pass
            try:
                layer.objects.active = was_active
            except (ReferenceError, RuntimeError):
                layer.objects.active = None
            if update_frame:
                scene.frame_set(scene.frame_current)        # the new rig posed at the frame shown
        else:
            deselect_all(context.view_layer)    # lands unselected: no orange outline over the new tree,
            context.view_layer.objects.active = rig  # the rig active (its properties show, ready to select)
            if update_frame:
                scene.frame_set(scene.frame_start)
        lod_build.hide_lower_levels(context, lod_objs)
    except BaseException:
        created.remove(context)
        raise
    timings["total"] = time.perf_counter() - t_total
    return {"collection": coll, "armature": rig, "mesh": mesh_obj, "action": action, "keys": rig_data.reduced,
            "budget": asset.budget, "lods": lod_objs, "asset": asset, "collision": caps,
            "impostor": impostor_files,
            "material": material, "leaves": leaf_obj, "leaf_material": leaf_mat,
            "leaf_polygons": sum(lv.leaves.quads for lv in asset.lods[:1] if lv.leaves is not None) if lod_objs
            else tree.leaves.polygons if leaf_obj is not None else 0, "timings": timings}


# ----------------------------------------------------------------------------- validation

def _validate(tree: Tree3D, collection_name: str, sides: int) -> None:
    if not collection_name or len(collection_name.encode()) > MAX_NAME - len(" Branches"):
        raise InputError(f"collection name '{collection_name}' must have 1 to {MAX_NAME - 9} characters")
    if not isinstance(sides, (int, np.integer)) or sides < 3:
        raise InputError(f"tubes need at least 3 sides (got {sides})")
    fps = float(tree.fps)
    if not (math.isfinite(fps) and 0.01 <= fps <= 1000):
        raise InputError(f"the tree's frame rate {tree.fps} is not usable; it must be between 0.01 and 1000 fps")
    radius = np.asarray(tree.radius, np.float64)
    if radius.shape != (tree.n_nodes,) or not np.isfinite(radius).all() or (radius < 0).any():
        raise InputError("the tree's radii must be one finite, non-negative value per node; rebuild the 3D tree")
    bones.check_positions(tree.parents, tree.nodes3d)        # shapes, finite positions, no zero-length bone
