"""What each node of a tree is (issue 33: a role per node instead of the ``meta["twigs"]
["first_node"]`` convention): the trunk, a limb measured from the video or grown by the generator,
a limb grown from a species where a reconstruction's crown showed no bark, a twig copied from the
tree's own forks; leaf-cluster bones get :data:`LEAF_CLUSTER`. Bone budgets keep the trunk and the
main limbs, Pivot Painter's hierarchy and the engine exports read the same roles.
"""
from __future__ import annotations

import numpy as np

from ..topology import branching_level

TRUNK, LIMB, GROWN_LIMB, TWIG, LEAF_CLUSTER = 0, 1, 2, 3, 4
ROLE_NAMES = ("trunk", "limb", "grown limb", "twig", "leaf cluster")


def first_twig_node(tree) -> int:
    """The index of the first twig node (twigs are appended after the tree's own nodes,
    :func:`core.detail.twigs.add_twigs`); ``n_nodes`` when the tree has none."""
    return int((tree.meta.get("twigs") or {}).get("first_node", tree.n_nodes))


def node_roles(tree) -> np.ndarray:
    """``(N,)`` int8 role of every node of ``tree`` (a :class:`~core.tree3d.Tree3D`): the root's
    chain up to the first fork is the trunk (branching level 0); nodes from
    :func:`first_twig_node` on are twigs; the others are limbs, :data:`GROWN_LIMB` where the
    reconstruction grew its crown's limbs (``meta["limbs"] == "grown"``)."""
    N = tree.n_nodes
    level = branching_level(np.asarray(tree.parents))
    limb = GROWN_LIMB if tree.meta.get("limbs") == "grown" else LIMB
    role = np.where(level == 0, TRUNK, limb).astype(np.int8)
    role[first_twig_node(tree):N] = TWIG
    return role


def role_counts(role: np.ndarray) -> dict[str, int]:
    """``{role name: count}`` of the roles present (for reports)."""
    counts = np.bincount(np.asarray(role, np.int64), minlength=len(ROLE_NAMES))
    return {ROLE_NAMES[k]: int(c) for k, c in enumerate(counts) if c}
