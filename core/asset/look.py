"""The tree's look as any writer needs it (issue 33): the branch mesh's shape settings, the bark's
colour and kind, the leaves' colours and image. Computed once from a :class:`~core.tree3d.Tree3D`
(its ``meta["mesh"]`` and ``meta["bark_colour"]``, its leaf clusters' video colours) with the
product's defaults (:class:`~core.detail.branch_mesh.MeshParams`); the Blender materials, the
baked textures and the engine exports all read this.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..detail import branch_mesh as bm
from ..detail.bark_texture import bark_ramp


@dataclass
class Look:
    """``mesh`` the branch mesh's settings (sides, curliness, bark kind, rings, seed);
    ``bark_colour (3,)`` sRGB the video's bark albedo or None (a default bark);
    ``bark_solid (4,)`` linear RGBA the bark as rendered on average (a viewer's flat colour);
    ``leaf_tint (3,)`` sRGB the leaf texture's colour; ``leaf_colour (3,)`` sRGB the foliage's
    median colour (None without leaves); ``leaf_image`` the user's leaf image path or None
    (a procedural leaf)."""

    mesh: bm.MeshParams
    bark_colour: np.ndarray | None
    bark_solid: tuple
    leaf_tint: np.ndarray | None
    leaf_colour: np.ndarray | None
    leaf_image: str | None = None


def mesh_params(tree, sides: int = 8, curliness: float | None = None, bark: str | None = None,
                seed: int | None = None, forks: str | None = None, relief_cm: float | None = None) -> bm.MeshParams:
    """The branch mesh settings: the given ones, else those recorded in ``tree.meta["mesh"]``
    (``curliness``, ``bark``, ``seed``, ``forks``, ``relief_cm``; written by ``pipeline.build_3d`` and
    ``growth.grow_tree``), else straight plain tubes (a tree made by hand, without a recorded look)
    with the default forks."""
    rec = tree.meta.get("mesh") or {}
    return bm.MeshParams(sides=sides,
                         curliness=float(rec.get("curliness", 0.0) if curliness is None else curliness),
                         bark=str(rec.get("bark", "none") if bark is None else bark),
                         seed=int(rec.get("seed", 0) if seed is None else seed),
                         forks=str(rec.get("forks", bm.MeshParams.forks) if forks is None else forks),
                         relief_cm=float(rec.get("relief_cm", bm.MeshParams.relief_cm) if relief_cm is None
                                         else relief_cm))


def bark_solid(colour=None) -> tuple:
    """Linear RGBA of the bark as rendered on average: the middle of its colour ramp
    (:func:`~core.detail.bark_texture.bark_ramp` of ``colour``), the bark material's solid-view
    colour."""
    dark, light = (np.asarray(c, np.float64) for c in bark_ramp(colour))
    return tuple(float(c) for c in 0.5 * (dark + light))


def leaf_colour(leaves) -> np.ndarray:
    """``(3,)`` sRGB colour of the foliage as the video shows it: the median of the clusters'
    colours per channel (the species model keeps the same median). The leaf material's
    solid-view colour."""
    return np.median(np.asarray(leaves.colour, np.float64), axis=0)


def leaf_tint(leaves) -> np.ndarray:
    """``(3,)`` sRGB colour of the procedural leaf texture: the foliage's median colour
    (:func:`leaf_colour`) brightened until 90 % of the clusters' colours lie at or below it in every
    channel (at most to 1 in its brightest channel). The leaf mesh's colour attribute holds each
    cluster's colour divided by it, so texture × colour = the video's colour, while a viewer that
    ignores vertex colours (Workbench's texture view, some engines) shows the foliage's hue and
    saturation. (A per-channel 90th percentile mixed the bright clusters' highlights and sky into
    every channel: a real cedar's yellow-green crown, HSV saturation 0.40, got a grey tint of 0.16.)"""
    colour = np.asarray(leaves.colour, np.float64)
    median = np.maximum(leaf_colour(leaves), 1e-3)
    k = float(np.percentile((colour / median).max(axis=1), 90))           # the brightening
    return median * float(np.clip(k, 1.0, 1.0 / median.max()))


def tree_look(tree, sides: int = 8, curliness: float | None = None, bark: str | None = None,
              leaf_image: str | None = None, forks: str | None = None, relief_cm: float | None = None) -> Look:
    """The :class:`Look` of ``tree`` (the given settings win over the recorded ones)."""
    params = mesh_params(tree, sides, curliness, bark, forks=forks, relief_cm=relief_cm)
    bm.check_params(params)
    colour = (tree.meta.get("bark_colour") or {}).get("colour")
    colour = None if colour is None else np.asarray(colour, np.float64)[:3]
    lv = tree.leaves
    leafy = lv is not None and lv.count > 0
    return Look(params, colour, bark_solid(colour), leaf_tint(lv) if leafy else None,
                leaf_colour(lv) if leafy else None, leaf_image)
