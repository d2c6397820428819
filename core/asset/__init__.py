"""The asset stage (issue 33): a :class:`~core.tree3d.Tree3D` as any writer needs it, in typed
numpy arrays — the rig (bones, rest pose, the motion's keys: :mod:`.rig`), the branch and leaf
meshes (:mod:`.meshes`), the look (:mod:`.look`) and each node's role (:mod:`.roles`). Blender's
builders (``operators/scene/``) only copy these into bpy; the game-engine exports read the same.

:func:`tree_asset` makes all of it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from ..tree3d import Tree3D
from .budget import BudgetReport, budget_rig
from .look import Look, tree_look
from .meshes import BranchMesh, LeafMesh, branch_arrays, leaf_arrays
from .rig import Rig, tree_rig


@dataclass
class TreeAsset:
    """``rig``, ``branches`` (None: no branch mesh asked for), ``leaves`` (None: no leaves),
    ``look``; ``timings`` seconds of each part (``rig arrays``: bones, rotations and key
    reduction; ``mesh arrays``; ``leaf arrays``; ``bone budget``); ``budget`` the bone budget's
    report (None: every bone kept)."""

    rig: Rig
    branches: BranchMesh | None
    leaves: LeafMesh | None
    look: Look
    timings: dict = field(default_factory=dict)
    budget: BudgetReport | None = None


def tree_asset(tree: Tree3D, *, mesh: bool = True, leaves: bool = True, sides: int = 8,
               curliness: float | None = None, bark: str | None = None, leaf_image: str | None = None,
               every_key: bool = False, bone_budget: int | None = None) -> TreeAsset:
    """Everything a writer copies of ``tree``: keys reduced within :data:`core.keys.KEY_TOLERANCE`
    (every frame with ``every_key``), the branch mesh with ``mesh``, the leaf bones and cards with
    ``leaves`` (when the tree has clusters), the look (``sides``, ``curliness``, ``bark`` and
    ``leaf_image`` win over what the tree records, :func:`.look.tree_look`); ``bone_budget``: the
    rig cut to at most that many bones, its motion re-fitted (:func:`.budget.budget_rig`)."""
    look = tree_look(tree, sides, curliness, bark, leaf_image)
    timings = {}
    t = time.perf_counter()
    # a budget that cuts the rig keys its re-fitted bones on every frame: no reduction to throw away
    n_bones = tree.n_nodes - 1 + (tree.leaves.count if leaves and tree.leaves is not None else 0)
    cut = bone_budget is not None and int(bone_budget) < n_bones
    rig = tree_rig(tree, every_key or cut, leaves)
    timings["rig arrays"] = time.perf_counter() - t
    t = time.perf_counter()
    branches = branch_arrays(tree, rig.rest, look.mesh) if mesh else None
    timings["mesh arrays"] = time.perf_counter() - t
    t = time.perf_counter()
    leafy = rig.leaf_keys is not None
    leaf_mesh = leaf_arrays(tree, look, rig.n_branch) if leafy else None
    timings["leaf arrays"] = time.perf_counter() - t
    report = None
    if bone_budget is not None:
        t = time.perf_counter()
        rig, branches, leaf_mesh, report = budget_rig(tree, rig, branches, leaf_mesh, int(bone_budget))
        timings["bone budget"] = time.perf_counter() - t
    return TreeAsset(rig, branches, leaf_mesh, look, timings, report)
