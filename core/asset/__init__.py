"""The asset stage (issue 33): a :class:`~core.tree3d.Tree3D` as any writer needs it, in typed
numpy arrays — the rig (bones, rest pose, the motion's keys: :mod:`.rig`), the branch and leaf
meshes (:mod:`.meshes`), the look (:mod:`.look`) and each node's role (:mod:`.roles`). Blender's
builders (``operators/scene/``) only copy these into bpy; the game-engine exports read the same.

:func:`tree_asset` makes all of it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..tree3d import Tree3D
from .budget import BudgetReport, budget_rig
from .collision import Capsule, capsules
from .lod import Lod, tree_lods
from .look import Look, tree_look
from .meshes import BranchMesh, LeafMesh, branch_arrays, leaf_arrays
from .pivot_painter import PivotPainter, pivot_elements
from .rig import Rig, tree_rig


@dataclass
class TreeAsset:
    """``rig``, ``branches`` (None: no branch mesh asked for), ``leaves`` (None: no leaves),
    ``look``; ``timings`` seconds of each part (``rig arrays``: bones, rotations and key
    reduction; ``mesh arrays``; ``leaf arrays``; ``lods``; ``bone budget``); ``budget`` the bone
    budget's report (None: every bone kept); ``lods`` the levels of detail (:mod:`.lod`; empty
    unless asked for; level 0 is ``branches`` and ``leaves``); ``pivots`` the rig's Pivot Painter 2
    elements (:mod:`.pivot_painter`; None unless asked for); ``capsules`` the trunk's and main limbs'
    collision capsules (:mod:`.collision`; empty unless asked for)."""

    rig: Rig
    branches: BranchMesh | None
    leaves: LeafMesh | None
    look: Look
    timings: dict = field(default_factory=dict)
    budget: BudgetReport | None = None
    lods: list[Lod] = field(default_factory=list)
    pivots: PivotPainter | None = None
    capsules: list[Capsule] = field(default_factory=list)

    def counts(self) -> dict[str, int]:
        """``{"bones", "triangles"}``: the rig's bones and the first level's triangles (branch
        polygons fanned, two a leaf card)."""
        tris = 0 if self.branches is None else int((self.branches.loop_total - 2).sum())
        tris += 0 if self.leaves is None else 2 * self.leaves.quads
        return {"bones": len(self.rig.names), "triangles": tris}


def tree_asset(tree: Tree3D, *, mesh: bool = True, leaves: bool = True, sides: int = 8,
               curliness: float | None = None, bark: str | None = None, leaf_image: str | None = None,
               forks: str | None = None, relief_cm: float | None = None,
               relief_map: tuple[np.ndarray, int] | None = None, every_key: bool = False,
               bone_budget: int | None = None, lods: int = 1,
               pivots: bool = False, collision: bool = False, as_levels: bool = False) -> TreeAsset:
    """Everything a writer copies of ``tree``: keys reduced within :data:`core.keys.KEY_TOLERANCE`
    (every frame with ``every_key``), the branch mesh with ``mesh``, the leaf bones and cards with
    ``leaves`` (when the tree has clusters), the look (``sides``, ``curliness``, ``bark``, ``forks``,
    ``relief_cm`` and ``leaf_image`` win over what the tree records, :func:`.look.tree_look`;
    ``relief_map`` the photo bark's height and repeats for the relief, :func:`.meshes.branch_arrays`); ``bone_budget``: the
    rig cut to at most that many bones, its motion re-fitted (:func:`.budget.budget_rig`); ``lods``
    ≥ 2: that many levels of detail (:func:`.lod.tree_lods`) on the same rig; ``pivots``: the rig's
    Pivot Painter 2 elements (:func:`.pivot_painter.pivot_elements`); ``collision``: capsules of the
    trunk and main limbs (:func:`.collision.capsules`, from the full rig); ``as_levels``: ``lods``
    levels even for one (LOD0 alone: a card LOD, the impostor's, follows it)."""
    look = tree_look(tree, sides, curliness, bark, leaf_image, forks, relief_cm)
    timings = {}
    t = time.perf_counter()
    # a budget that cuts the rig keys its re-fitted bones on every frame: no reduction to throw away
    n_bones = tree.n_nodes - 1 + (tree.leaves.count if leaves and tree.leaves is not None else 0)
    cut = bone_budget is not None and int(bone_budget) < n_bones
    rig = tree_rig(tree, every_key or cut, leaves)
    timings["rig arrays"] = time.perf_counter() - t
    t = time.perf_counter()
    branches = branch_arrays(tree, rig.rest, look.mesh, relief_map=relief_map) if mesh else None
    timings["mesh arrays"] = time.perf_counter() - t
    t = time.perf_counter()
    leafy = rig.leaf_keys is not None
    leaf_mesh = leaf_arrays(tree, look, rig.n_branch) if leafy else None
    timings["leaf arrays"] = time.perf_counter() - t
    levels: list[Lod] = []
    if lods > 1 or as_levels:
        t = time.perf_counter()
        levels = tree_lods(tree, rig.rest, look, branches, leaf_mesh, int(lods))
        timings["lods"] = time.perf_counter() - t
    caps: list[Capsule] = capsules(tree, rig) if collision else []
    report = None
    if bone_budget is not None:
        t = time.perf_counter()
        rig, branches, leaf_mesh, report = budget_rig(tree, rig, branches, leaf_mesh, int(bone_budget))
        if levels and report.bone_of is not None:       # every level's vertices onto the kept bones
            bone_of = report.bone_of
            levels = [replace(lv, branches=None if lv.branches is None else replace(
                lv.branches, bone=bone_of[lv.branches.bone].astype(np.int32)),
                leaves=None if lv.leaves is None else replace(lv.leaves, bone=bone_of[lv.leaves.bone].astype(np.int32)))
                for lv in levels]
        timings["bone budget"] = time.perf_counter() - t
    if levels:
        levels[0] = replace(levels[0], branches=branches, leaves=leaf_mesh)
    pp = None
    if pivots:
        t = time.perf_counter()
        pp = pivot_elements(tree, rig)
        timings["pivot painter"] = time.perf_counter() - t
    return TreeAsset(rig, branches, leaf_mesh, look, timings, report, levels, pp, caps)
