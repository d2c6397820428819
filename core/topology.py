"""Tree topology from a parent array ``parents (N,)`` (``-1`` at the root, parents need not
precede children): edges, children, a root-first order, chains between anchors and branching
levels. Shared by the 2D skeleton, the 3D stages, the details and generation.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def edges_of(parents: np.ndarray) -> np.ndarray:
    """``(N-1, 2)`` (parent, child) index pairs, one per node with a parent, in node order."""
    parents = np.asarray(parents)
    c = np.flatnonzero(parents >= 0)
    return np.stack([parents[c], c], axis=1)


def children_lists(parents: np.ndarray) -> list[list[int]]:
    """Children of every node, in index order."""
    ch: list[list[int]] = [[] for _ in parents]
    for c, p in enumerate(parents):
        if p >= 0:
            ch[p].append(c)
    return ch


def topological_order(parents: np.ndarray) -> np.ndarray:
    """Node indices root first, every parent before its children (breadth first)."""
    ch = children_lists(parents)
    order = [int(r) for r in np.flatnonzero(parents < 0)]
    i = 0
    while i < len(order):
        order.extend(ch[order[i]])
        i += 1
    return np.array(order, int)


@dataclass
class Chains:
    """How nodes sit on chains between *anchors* (a chosen node set; chains run between them).

    ``up (N,)`` nearest strict ancestor that is an anchor (−1 for the root); ``down (N,)`` for a
    node with exactly one child, the first anchor below it (−1 otherwise); ``arc (N,)`` path length
    from ``up`` to the node along the skeleton (same units as the positions).
    """

    up: np.ndarray
    down: np.ndarray
    arc: np.ndarray

    def fraction(self, nodes: np.ndarray) -> np.ndarray:
        """Share of the way from ``up`` to ``down`` for chain ``nodes`` (0..1)."""
        return self.arc[nodes] / np.maximum(self.arc[self.down[nodes]], 1e-9)


def chains(parents: np.ndarray, pos: np.ndarray, anchors: np.ndarray) -> Chains:
    """:class:`Chains` for ``parents (N,)``, positions ``pos (N, D)`` and ``anchors (N,)`` bool."""
    N = len(parents)
    order = topological_order(parents)
    ch = children_lists(parents)
    up = np.full(N, -1)
    arc = np.zeros(N)
    for n in order:
        p = parents[n]
        if p >= 0:
            up[n] = p if anchors[p] else up[p]
            arc[n] = float(np.linalg.norm(pos[n] - pos[p])) + (0.0 if anchors[p] else arc[p])
    down = np.full(N, -1)
    for n in order[::-1]:
        if len(ch[n]) == 1:
            c = ch[n][0]
            down[n] = c if anchors[c] else down[c]
    return Chains(up, down, arc)


def node_depths(parents: np.ndarray) -> np.ndarray:
    """``(N,)`` edges from the root to each node."""
    parents = np.asarray(parents)
    d = np.zeros(len(parents), int)
    for n in topological_order(parents):
        if parents[n] >= 0:
            d[n] = d[parents[n]] + 1
    return d


def subtree_sizes(parents: np.ndarray) -> np.ndarray:
    """``(N,)`` nodes in each node's subtree (itself included): the deepest level first, each
    level's counts added to its parents' at once."""
    parents = np.asarray(parents)
    size = np.ones(len(parents), np.int64)
    depth = node_depths(parents)
    for d in range(int(depth.max(initial=0)), 0, -1):
        at = np.flatnonzero(depth == d)
        np.add.at(size, parents[at], size[at])
    return size


def without_nodes(parents: np.ndarray, drop: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tree less the nodes ``drop (N,)`` bool (whole subtrees: no kept node may hang from a
    dropped one). Returns ``keep (K,)`` the old indices of the kept nodes in their order, their
    ``parents (K,)`` re-indexed, and ``index (N,)`` each old node's new index (-1: dropped)."""
    parents = np.asarray(parents, np.int64)
    keep = np.flatnonzero(~np.asarray(drop, bool))
    index = -np.ones(len(parents), np.int64)
    index[keep] = np.arange(len(keep))
    return keep, np.where(parents[keep] >= 0, index[np.maximum(parents[keep], 0)], -1), index


def subtree_masks(parents: np.ndarray, roots: np.ndarray) -> np.ndarray:
    """``(R, N)`` bool: node n is in the subtree of ``roots[r]`` (itself included)."""
    parents = np.asarray(parents)
    n = len(parents)
    anc = np.arange(n)
    member = np.zeros((len(roots), n), bool)
    for _ in range(n):                         # walk every node up one level at a time (depth steps)
        member |= anc[None] == np.asarray(roots)[:, None]
        up = anc >= 0
        if not up.any():
            break
        anc = np.where(up, parents[np.maximum(anc, 0)], -1)
    return member


def subtree(parents: np.ndarray, roots: np.ndarray) -> np.ndarray:
    """``(N,)`` bool: ``roots`` and every node below them."""
    return subtree_masks(parents, np.asarray(roots, np.int64)).any(axis=0)


def branching_level(parents: np.ndarray) -> np.ndarray:
    """Branching order per node: 0 on the trunk, +1 below every node with two or more children."""
    ch = children_lists(parents)
    level = np.zeros(len(parents), np.int32)
    for n in topological_order(parents):
        p = parents[n]
        if p >= 0:
            level[n] = level[p] + (1 if len(ch[p]) >= 2 else 0)
    return level


def trunk_chain(parents: np.ndarray) -> np.ndarray:
    """``(K,)`` node indices from the root (0) along its single-child successors to the first
    fork (inclusive), or to the last node of a tree without one: a tree's trunk."""
    parents = np.asarray(parents)
    kids = children_lists(parents)
    chain = [0]
    while len(kids[chain[-1]]) == 1:
        chain.append(kids[chain[-1]][0])
    return np.asarray(chain, np.int64)


def trunk_top(parents: np.ndarray) -> int:
    """The node where the single chain from the root ends (its first fork, or the last node of a
    tree without one): a palm's crown top."""
    return int(trunk_chain(parents)[-1])
