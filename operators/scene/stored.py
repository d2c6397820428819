"""The reconstructed trees kept in the .blend, so every button that works on a reconstruction works
on any tree of the file after it is saved and reopened.

Reconstruct stores the :class:`~...core.tree3d.Tree3D` it built in the tree's collection, as the ID
property :data:`KEY` ``{"tree": bytes of the tree's .npz (core.tree3d.tree_bytes), "video":
absolute path, "made": time.time()}``: saved with the file, removed with the collection, undone
with the Reconstruct. The leading underscore keeps it out of the Custom Properties panel.

:func:`selected` picks the tree a button works on: the active object's tree, else the active
collection's, else the file's only one.
"""
from __future__ import annotations

import json
import os
import time

import bpy

from ...core.errors import InputError
from ...core.tree3d import Tree3D, tree_bytes, tree_from_bytes
from .trees import owners

#: the ID property on a reconstructed tree's collection
KEY = "_tree_from_video"

_decoded: dict = {}       # (session_uid, made) -> Tree3D, so a button press decodes a tree once


def store_tree(coll, tree: Tree3D, video: str) -> None:
    """Keep ``tree`` (reconstructed from ``video``) in its collection ``coll``."""
    coll[KEY] = {"tree": tree_bytes(tree), "video": os.path.abspath(video), "made": time.time()}


def is_tree(coll) -> bool:
    return coll is not None and coll.get(KEY) is not None


def tree_collections() -> list:
    """The collections of this file that hold a reconstructed tree, in name order."""
    return [c for c in bpy.data.collections if is_tree(c)]


def load_tree(coll) -> Tree3D:
    """The tree kept in ``coll`` (exactly as it was built), named after the collection."""
    group = coll[KEY]
    key = (coll.session_uid, float(group["made"]))
    if key not in _decoded:
        _decoded.clear()                          # one tree at a time: they can be large
        _decoded[key] = tree_from_bytes(bytes(group["tree"]), f"the tree kept in collection '{coll.name}'")
    tree = _decoded[key]
    tree.name = coll.name
    return tree


def video_of(coll) -> str:
    return str(coll[KEY]["video"])


def selected(context) -> tuple:
    """``(collection or None, why)``: the reconstructed tree a button works on — the one whose
    objects are selected, else the active object's, else the active collection (clicked in the
    Outliner), else the file's only one — and a short note (which one, or why there is none) for
    the panel."""
    chosen = owners(getattr(context, "selected_objects", None) or (), is_tree)
    if len(chosen) != 1 and getattr(context, "active_object", None) is not None:
        chosen = owners([context.active_object], is_tree)
    if len(chosen) == 1:
        return chosen[0], "selected"
    layer = getattr(getattr(context, "view_layer", None), "active_layer_collection", None)
    if layer is not None and is_tree(layer.collection):
        return layer.collection, "active collection"
    trees = tree_collections()
    if len(trees) == 1:
        return trees[0], "the only one in the file"
    if not trees:
        return None, "Reconstruct a tree first"
    return None, f"Select one of the {len(trees)} reconstructed trees"


def selected_tree(context, what: str) -> Tree3D:
    """The tree :func:`selected` picks; :class:`InputError` saying how to get one for ``what``."""
    coll, why = selected(context)
    if coll is not None:
        return load_tree(coll)
    n = len(tree_collections())
    if n == 0:
        raise InputError(f"{what}: this file has no reconstructed tree; press Reconstruct first, "
                         "or pick a species from the library or a file")
    raise InputError(f"{what}: this file has {n} reconstructed trees; select the one to use "
                     "(click its rig or mesh, or its collection in the Outliner)")


#: the ID property on a generated tree's collection: its rest pose and the cuts placed in it
GROWN_KEY = "_tree_from_video_grown"


def store_grown(coll, tree: Tree3D, cuts: list[dict], inputs: dict | None = None) -> None:
    """Keep what Save Cut and Place Cut read of a generated ``tree`` in its collection ``coll``: its
    rest pose (frame 1 only: a few kB, not the motion), its cuts ``[{"path", "at"}]`` (``at``
    metres in the tree's frame or None) and what it grew from (``inputs``,
    :func:`core.generate.regrow.inputs_doc`: species, envelope, settings; None: not kept)."""
    rest = Tree3D(tree.parents, tree.nodes3d[:1], tree.radius, tree.level, tree.fps, tree.name, tree.meta)
    coll[GROWN_KEY] = {"tree": tree_bytes(rest), "cuts": json.dumps(cuts), "made": time.time(),
                       "inputs": json.dumps(inputs)}


def has_grown_inputs(coll) -> bool:
    """Whether the generated tree of ``coll`` kept what it grew from (a poll's check: not parsed)."""
    return is_grown(coll) and str(coll[GROWN_KEY].get("inputs", "null")) != "null"


def grown_inputs(coll) -> dict | None:
    """What the generated tree of ``coll`` grew from (:func:`store_grown`), or None."""
    if not is_grown(coll):
        return None
    return json.loads(str(coll[GROWN_KEY].get("inputs", "null")))


def is_grown(coll) -> bool:
    return coll is not None and coll.get(GROWN_KEY) is not None


def grown_cuts(coll) -> list[dict]:
    """The cuts placed in the generated tree of ``coll`` (:func:`store_grown`)."""
    return json.loads(str(coll[GROWN_KEY]["cuts"])) if is_grown(coll) else []


def rig_tree(context) -> tuple:
    """``(collection, Tree3D at rest)`` of the tree whose rig is the active object (reconstructed or
    generated), else :class:`InputError` saying what to select."""
    ob = getattr(context, "active_object", None)
    if ob is None or ob.type != "ARMATURE":
        raise InputError("select a tree's rig (its armature) and, in Pose Mode, the bones of a branch")
    found = owners([ob], lambda c: is_tree(c) or is_grown(c))
    if not found:
        raise InputError(f"'{ob.name}' is not the rig of a reconstructed or generated tree of this file "
                         "(a forest's trees keep no tree to cut from); select one")
    return found[0], kept_tree(found[0])


def kept_tree(coll) -> Tree3D:
    """The tree kept in ``coll``: a reconstruction's (:func:`load_tree`) or a generated tree's rest."""
    if is_tree(coll):
        return load_tree(coll)
    tree = tree_from_bytes(bytes(coll[GROWN_KEY]["tree"]), f"the tree kept in collection '{coll.name}'")
    tree.name = coll.name
    return tree


def clear() -> None:
    _decoded.clear()
