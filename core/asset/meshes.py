"""The tree's meshes as any writer copies them (issue 33): the skinned branch tubes and the leaf
cards with their flap, in typed arrays (no bpy). Every vertex is carried by one bone with weight 1.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..detail import branch_mesh as bm
from ..detail.bark_texture import bark_textures
from ..detail.forks import pipe_heads
from ..detail.leaf_clusters import flap_weights, leaf_flap_offsets, leaf_mesh
from ..detail.relief import RELIEF_RINGS, RELIEF_SIDES, relief_offsets
from ..tree3d import Tree3D
from .look import Look


@dataclass
class BranchMesh:
    """Tapered tubes, one per branch bone (:func:`core.detail.branch_mesh.tube_arrays`): ``co (V,
    3)`` metres at rest; polygons as ``loop_vert (L,)``, ``loop_start``, ``loop_total (P,)``,
    ``smooth (P,)`` bool; ``uv (L, 2)`` on the bark's UV square; ``bone (V,)`` int32 the rig's
    bone carrying each vertex (an index into ``Rig.names``)."""

    co: np.ndarray
    loop_vert: np.ndarray
    loop_start: np.ndarray
    loop_total: np.ndarray
    smooth: np.ndarray
    uv: np.ndarray
    bone: np.ndarray


@dataclass
class LeafFlap:
    """Every leaf card's flap about its stem as four non-negative shape keys (+C, −C, +S, −S of
    :func:`core.detail.leaf_clusters.leaf_flap_offsets`): ``offsets (4, V, 3)`` metres, ``weights
    (F, 4)`` in [0, 1] per frame, ``names`` the keys' names (safe in USD)."""

    offsets: np.ndarray
    weights: np.ndarray
    names: tuple[str, ...] = ("Leaf flap sin pos", "Leaf flap sin neg", "Leaf flap cos pos", "Leaf flap cos neg")


@dataclass
class LeafMesh:
    """The leaf cards of all clusters, quads (vertices ``4q … 4q + 3`` are card ``q``): ``co (V,
    3)`` metres at rest, ``uv (V, 2)``, ``colour (V, 3)`` sRGB each cluster's video colour divided by
    the look's leaf tint (texture × colour = the video's), ``bone (V,)`` int32 the rig's bone
    carrying each vertex (an index into ``Rig.names``), ``flap`` (None when the leaves do not
    flap)."""

    co: np.ndarray
    uv: np.ndarray
    colour: np.ndarray
    bone: np.ndarray
    flap: LeafFlap | None

    @property
    def quads(self) -> int:
        return len(self.co) // 4


def branch_arrays(tree: Tree3D, rest: np.ndarray, params: bm.MeshParams, widen: float = 1.0,
                  relief_map: tuple[np.ndarray, int] | None = None) -> BranchMesh:
    """The :class:`BranchMesh` of ``tree`` at rest, its bones' rest rotations ``rest (B, 3, 3)``,
    radii × ``widen`` floored at 10⁻⁴ of the tree's size (no zero-width tube); joined forks follow
    the tree's measured pipe exponent (:func:`pipe_exponent`). With ``params.relief_cm`` > 0 the
    bark's height map moves the vertices (:mod:`core.detail.relief`, on at least
    :data:`~core.detail.relief.RELIEF_SIDES` sides and :data:`~core.detail.relief.RELIEF_RINGS`
    rings): ``relief_map`` = ``(height (H, W) in [0, 1], repeats over the UV square)``, the photo
    bark's; None: the procedural bark's (:func:`relief_height`)."""
    r_head, r_tail = (widen * r for r in bm.branch_radii(tree.parents, tree.radius))
    delta = pipe_exponent(tree)
    r_head = pipe_heads(tree.parents, r_head, r_tail, delta)      # every level: the joined forks' radii
    floor = 1e-4 * max(float(np.ptp(tree.nodes3d[0], axis=0).max()), 1e-3)
    relief = float(params.relief_cm) > 0
    sides, rings = params.sides, params.rings
    if relief:
        sides, rings = max(sides, RELIEF_SIDES), max(params.ring_count(), RELIEF_RINGS)
    g = bm.tube_arrays(tree.nodes3d[0], tree.parents, rest, np.maximum(r_head, floor),
                       np.maximum(r_tail, floor), sides, curliness=params.curliness, bark=params.bark,
                       rings=rings, seed=params.seed, forks=params.forks,
                       pipe_exponent=delta)
    if relief:
        height, repeats = relief_map if relief_map is not None else (relief_height(params.bark), 1)
        g["co"] = g["co"] + relief_offsets(g, height, repeats, float(params.relief_cm) / 100.0)
    return BranchMesh(g["co"].astype(np.float32), g["loop_vert"].astype(np.int32), g["loop_start"].astype(np.int32),
                      g["loop_total"].astype(np.int32), np.asarray(g["smooth"], bool), g["uv"].astype(np.float32),
                      np.asarray(g["vert_bone"], np.int32))


@lru_cache(maxsize=4)
def relief_height(bark: str) -> np.ndarray:
    """``(S, S)`` in [0, 1] (read-only, cached: a forest asks once): the procedural bark's height
    map of kind ``bark``, the one its material's normal map is made from
    (:func:`core.detail.bark_texture.bark_textures`)."""
    height = bark_textures(None, bark).height
    height.flags.writeable = False
    return height


def pipe_exponent(tree: Tree3D) -> float:
    """The pipe model's exponent Δ a joined fork keeps: the tree's own median
    (``meta["allometry"]["pipe_exponent"]``) within [1.5, 3.5], else Leonardo's 2."""
    delta = (tree.meta.get("allometry") or {}).get("pipe_exponent")
    return 2.0 if delta is None else float(np.clip(delta, 1.5, 3.5))


def leaf_arrays(tree: Tree3D, look: Look, first_bone: int = 0) -> LeafMesh:
    """The :class:`LeafMesh` of ``tree``'s clusters (cluster ``s`` on bone ``first_bone + s``: the
    rig's leaf bones follow its branch bones), with the flap of its cards when ``leaf_angle`` and
    ``leaf_hz`` are positive."""
    lv = tree.leaves
    assert lv is not None
    g = leaf_mesh(lv)
    assert look.leaf_tint is not None
    colour = np.clip(g["colour"] / look.leaf_tint, 0.0, 1.0).astype(np.float32)
    flap = None
    if lv.leaf_angle > 0 and lv.leaf_hz > 0:
        C, S, _ = leaf_flap_offsets(g["co"], lv.leaf_angle, lv.seed)
        flap = LeafFlap(np.stack([C, -C, S, -S]).astype(np.float32), flap_weights(tree.n_frames, tree.fps, lv.leaf_hz))
    return LeafMesh(g["co"].astype(np.float32), g["uv"].astype(np.float32), colour,
                    (first_bone + np.asarray(g["cluster"])).astype(np.int32), flap)
