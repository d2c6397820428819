"""The add-on's trees in the file: a tree is a collection that :func:`.build.build_tree` made (a
reconstruction, a generated tree, each tree of a forest), marked with the custom property
:data:`TREE_KEY` and holding the tree's armature, branch mesh and leaves. A forest is a collection
whose children are trees. Trees built before the mark existed are recognised by their rig
(an armature ``"<collection> Rig"`` directly in the collection)."""
from __future__ import annotations

import bpy

from .action_api import rig_action

#: custom property on a tree's collection (set by build_tree; the leading underscore keeps it out
#: of the Custom Properties panel)
TREE_KEY = "_tree_from_video_built"


def mark(coll) -> None:
    """Mark ``coll`` as a tree built by the add-on."""
    coll[TREE_KEY] = 1


def is_tree(coll) -> bool:
    """True if the collection ``coll`` is a tree built by the add-on."""
    if coll is None:
        return False
    if coll.get(TREE_KEY):
        return True
    rig = coll.objects.get(f"{coll.name} Rig")
    return rig is not None and rig.type == "ARMATURE"


def trees_in(coll) -> list:
    """The trees ``coll`` is or holds (itself, or a forest's trees by name), else ``[]``."""
    if coll is None:
        return []
    if is_tree(coll):
        return [coll]
    return sorted((c for c in coll.children_recursive if is_tree(c)), key=lambda c: c.name)


def holds_trees(coll) -> bool:
    """True if ``coll`` is a tree or holds one (a forest): what the Export › Tree list offers."""
    return is_tree(coll) or any(is_tree(c) for c in coll.children_recursive)


def file_trees() -> list:
    """Every tree in the file (``bpy.data``), by name."""
    return sorted((c for c in bpy.data.collections if is_tree(c)), key=lambda c: c.name)


def owners(objects, is_one=None) -> list:
    """The collections owning ``objects`` that are trees (``is_one``, default :func:`is_tree`),
    each once, by name."""
    is_one = is_one or is_tree
    found = {}
    for ob in objects:
        for coll in ob.users_collection:
            if coll.name not in found and is_one(coll):
                found[coll.name] = coll
    return [found[k] for k in sorted(found)]


def scene_trees(scene, exclude=None) -> list:
    """The trees linked into ``scene`` (a forest's trees too), by name, ``exclude`` left out."""
    found = [c for c in scene.collection.children_recursive if is_tree(c) and c != exclude]
    return sorted(found, key=lambda c: c.name)


def selected_trees(context) -> list:
    """The trees the user points at, by name: those owning a selected object; else the active
    object's tree (a new tree lands unselected with its rig active); else the active collection
    if it is a tree or holds trees (a forest clicked in the Outliner); else the file's only tree."""
    found = owners(context.selected_objects or ())
    if not found and context.active_object is not None:
        found = owners([context.active_object])
    layer = getattr(context.view_layer, "active_layer_collection", None)
    if not found and layer is not None and layer.collection != context.scene.collection:
        found = trees_in(layer.collection)
    if not found:
        every = file_trees()
        found = every if len(every) == 1 else []
    return found


def tree_objects(coll) -> list:
    """The objects of tree ``coll`` an export writes: its armature and meshes (branches, leaves, or
    its levels of detail and their LOD group empty)."""
    return [ob for ob in coll.all_objects if ob.type in ("ARMATURE", "MESH")
            or (ob.type == "EMPTY" and ob.get("fbx_type") == "LodGroup")]


def tree_size(coll) -> int:
    """Bones × animated frames of tree ``coll`` (what an export's time grows with), at least 1."""
    size = 0
    for ob in coll.all_objects:
        if ob.type != "ARMATURE":
            continue
        action = rig_action(ob)
        frames = 1
        if action is not None:
            start, end = action.frame_range
            frames = max(int(round(end - start)) + 1, 1)
        size += len(ob.data.bones) * frames
    return max(size, 1)
