"""A tree standing again: another tree of a forest that is one of its variants
(:mod:`core.generate.forest`), sharing the variant's armature, meshes and motion.

The instance is a collection of its own (marked a tree, :mod:`.trees`) holding a copy of the
variant's rig object and of each of its mesh objects: the copies share the variant's data (armature,
meshes, their vertex groups and the leaves' flap keys), so the .blend stores them once. The rig
plays the variant's action through one NLA strip that starts ``offset`` frames into the loop and
repeats it, so the instance sways out of step with its variant (the variant's action must be a
loop: frame ``1 + period`` equal to frame 1, ``meta["periodic"]`` / :func:`core.loop.loop_tree`).

:func:`.action_api.rig_action` is the action a rig plays, either way; exports play an instance as its variant
does, from the loop's first frame (:func:`played_as_action`).
"""
from __future__ import annotations

from contextlib import contextmanager

import bpy

from .action_api import rig_action
from .objects import unique_collection_name
from .trees import mark

#: custom property on an instance's collection: the name of the tree collection it stands again
INSTANCE_KEY = "_tree_from_video_instance_of"
#: the NLA track of an instance's motion
TRACK = "Tree from Video sway"


def instance_tree(built: dict, name: str, offset: int, period: int) -> dict:
    """A new collection ``name`` (made unique) standing the built tree ``built`` (the dict
    :func:`.build.build_tree` returned) again: its rig and meshes copied, sharing their data, the
    copies' parents and Armature modifiers pointed at the new rig, which plays the variant's action
    from frame ``1 + offset`` of its loop of ``period`` frames (``0 ≤ offset < period``), repeated to
    cover at least two periods from the scene's frame 1. Not linked anywhere; returns the dict
    ``build_tree`` returns for it (``"action"`` the shared one, ``"instance_of"`` the variant's
    collection name)."""
    if not 0 <= offset < period:
        raise ValueError(f"offset {offset} outside [0, {period})")
    src_coll, src_rig = built["collection"], built["armature"]
    action = rig_action(src_rig)
    coll = bpy.data.collections.new(unique_collection_name(name))
    made: list = []
    try:
        rig = src_rig.copy()
        made.append(rig)
        rig.name = f"{coll.name} Rig"
        coll.objects.link(rig)
        ad = rig.animation_data or rig.animation_data_create()
        ad.action = None
        for track in list(ad.nla_tracks):
            ad.nla_tracks.remove(track)
        if action is not None:
            track = ad.nla_tracks.new()
            track.name = TRACK
            # the strip starts `offset` frames before frame 1, so frame 1 plays the loop's frame 1 + offset
            strip = track.strips.new(action.name, 1 - int(offset), action)
            strip.action_frame_start, strip.action_frame_end = 1.0, 1.0 + float(period)
            strip.repeat = 3.0
            strip.extrapolation = "HOLD"
        copies = {src_rig.name: rig}
        for ob in src_coll.all_objects:
            if ob is src_rig:
                continue
            dup = ob.copy()
            made.append(dup)
            dup.name = ob.name.replace(src_coll.name, coll.name, 1) if ob.name.startswith(src_coll.name) \
                else f"{coll.name} {ob.name}"
            coll.objects.link(dup)
            copies[ob.name] = dup
        for ob in made[1:]:
            src_parent = ob.parent
            if src_parent is not None and src_parent.name in copies:
                ob.parent = copies[src_parent.name]
            for mod in ob.modifiers:
                if mod.type == "ARMATURE" and mod.object is src_rig:
                    mod.object = rig
        for key in src_coll.keys():                   # the engine files and marks kept with the tree
            coll[key] = src_coll[key]
        mark(coll)
        coll[INSTANCE_KEY] = src_coll.name
    except BaseException:
        for ob in made:
            bpy.data.objects.remove(ob, do_unlink=True)
        bpy.data.collections.remove(coll)
        raise
    mesh, leaves = (copies.get(built[k].name) if built.get(k) is not None else None for k in ("mesh", "leaves"))
    return {**built, "collection": coll, "armature": rig, "mesh": mesh, "leaves": leaves, "action": action,
            "instance_of": src_coll.name, "timings": {}}


@contextmanager
def played_as_action(objects):
    """While exporting: each instance rig among ``objects`` plays its variant's action as its
    active action with its NLA off (what the exporters sample and name), from the loop's first
    frame; put back afterwards."""
    changed = []
    for ob in objects:
        ad = getattr(ob, "animation_data", None)
        if ob.type != "ARMATURE" or ad is None or ad.action is not None:
            continue
        action = rig_action(ob)
        if action is None:
            continue
        changed.append((ad, ad.use_nla))
        ad.action = action
        if hasattr(ad, "action_slot") and len(getattr(action, "slots", ())):
            ad.action_slot = action.slots[0]
        ad.use_nla = False
    try:
        yield
    finally:
        for ad, use_nla in changed:
            ad.action = None
            ad.use_nla = use_nla
