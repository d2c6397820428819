"""A forest in the scene: generated trees built into one collection a few at a time (so a modal
operator keeps Blender responsive), each in a scratch scene, sharing one bark and one leaf material.
A variant that stands more than once (:func:`core.generate.forest.forest_slots`) is built once;
its other trees are instances sharing its data and motion (:mod:`.instances`).
"""
from __future__ import annotations

import time

import bpy

from ...core.asset.game import GameSettings
from ...core.generate.forest import instance_offsets, shares_variants
from ...core.loop import maybe_loop
from .build import build_tree
from .game import build_kwargs, keep_engine_files
from .instances import instance_tree
from .objects import remove_collection, unique_collection_name
from .timing import fit_scene_timing
from .trees import scene_trees


class ForestBuild:
    """Builds the grown trees into one collection ``name``, a few per :meth:`step`: a tree per slot
    at its position, turn and size, ``trees[slot.variant]`` built the first time its variant stands
    and instanced after that (:func:`.instances.instance_tree`, out of step by
    :func:`core.generate.forest.instance_offsets`); with the branch mesh's ``curliness``,
    ``bark``, ``forks`` and ``relief_cm``; all trees share the first one's bark and leaf materials; ``loop_s`` > 0 cuts each
    tree's motion to a seamless loop of about that many seconds (:func:`core.loop.maybe_loop`; a
    shared variant is looped over its own period when ``loop_s`` is 0); ``game`` the game settings
    each tree is built with (:mod:`.game`); ``bark_maps`` the bark from photos of bark (None:
    procedural). ``remove()`` undoes it all."""

    def __init__(self, context, name: str, model, trees, slots, *, curliness: float | None = None,
                 bark: str | None = None, forks: str | None = None, relief_cm: float | None = None,
                 loop_s: float = 0.0,
                 game: GameSettings | None = None, bark_maps=None):
        self.trees, self.slots, self.model = trees, slots, model
        self.game = game or GameSettings()
        self.curliness, self.bark, self.loop_s, self.bark_maps = curliness, bark, loop_s, bark_maps
        self.forks, self.relief_cm = forks, relief_cm
        self.coll = bpy.data.collections.new(name)
        context.scene.collection.children.link(self.coll)
        self.built: list[dict] = []
        self.variants: dict[int, tuple[dict, float, int]] = {}   # variant → (built, its first size, period)
        self.shared = shares_variants(slots)
        self.materials: dict | None = None
        self.k = 0
        self.frames = 0                                   # the longest built animation (a loop's L + 1)
        self.elapsed = 0.0

    @property
    def finished(self) -> bool:
        return self.k >= len(self.slots)

    def _loop_seconds(self, tree) -> float:
        if self.loop_s > 0 or not self.shared:
            return self.loop_s
        periodic = tree.meta.get("periodic")
        if not periodic:
            raise ValueError(f"'{tree.name}' stands more than once but does not sway in a loop "
                             "(grow it with core.generate.forest.generate_forest)")
        return float(periodic["frames"]) / float(tree.fps)

    def step(self, context, budget_s: float) -> None:
        t0 = time.perf_counter()
        while not self.finished and time.perf_counter() - t0 < budget_s:
            slot = self.slots[self.k]
            name = unique_collection_name(f"{self.coll.name} {self.k:03d}")
            if slot.variant in self.variants:
                first, size, period = self.variants[slot.variant]
                offset = int(instance_offsets(self.slots, self.trees[0].fps, period)[self.k])
                built = instance_tree(first, name, offset, period)
                self.coll.children.link(built["collection"])
                scale = slot.scale / size
            else:
                built = self._build(context, slot, name)
                scale = 1.0
            self.built.append(built)
            rig = built["armature"]
            rig.location = tuple(slot.position)
            rig.rotation_euler = (0.0, 0.0, slot.rotation_z)
            rig.scale = (scale, scale, scale)
            if self.materials is None:
                self.materials = {"bark": built["material"],
                                  "leaf": built["leaf_material"]}
            self.k += 1
        if self.finished:
            scene = context.scene                         # the artist's frame and selection are kept
            mine = {b["collection"].name for b in self.built}
            others = [c for c in scene_trees(scene) if c.name not in mine]
            fit_scene_timing(scene, self.trees[0].fps, self.frames, first=not others)
            scene.frame_set(scene.frame_current)          # every new rig posed at the frame shown
        self.elapsed += time.perf_counter() - t0

    def _build(self, context, slot, name: str) -> dict:
        """The variant of ``slot`` built the first time it stands (kept for its instances)."""
        grown = self.trees[slot.variant]
        tree = maybe_loop(grown, self._loop_seconds(grown))[0]
        self.frames = max(self.frames, tree.n_frames)
        # each tree is built in a scratch scene: its edit-mode switches then update a view layer
        # holding one tree, not the whole forest so far (that made building quadratic)
        scratch = bpy.data.scenes.new("Tree from Video build")
        try:
            with context.temp_override(scene=scratch, view_layer=scratch.view_layers[0]):
                built = build_tree(bpy.context, tree, name, materials=self.materials,
                                   curliness=self.curliness, bark=self.bark, forks=self.forks,
                                   relief_cm=self.relief_cm,
                                   update_frame=False,
                                   bark_maps=self.bark_maps, **build_kwargs(self.game))
            keep_engine_files(built, tree, self.game)
            scratch.collection.children.unlink(built["collection"])
            self.coll.children.link(built["collection"])
        finally:
            bpy.data.scenes.remove(scratch)
        self.variants[slot.variant] = (built, slot.scale, tree.n_frames - 1)
        return built

    def remove(self) -> None:
        try:
            remove_collection(self.coll)
        except ReferenceError:
            pass
