"""The impostor (issue 33, ``--impostor``): the tree seen from a hemisphere of directions, each view
a cell of one atlas, and a crossed-billboard card mesh as the last LOD.

Hemi-octahedral layout (the one Unreal's Impostor Baker "Upper Hemisphere" and the octahedral
impostor shaders use): cell ``(i, j)`` of an ``N × N`` grid has the grid point
``g = (2(i + ½)/N − 1, 2(j + ½)/N − 1)`` ∈ (−1, 1)²; rotated 45°, ``p = ((gx + gy)/2, (gx − gy)/2)``
lies in the diamond ``|px| + |py| ≤ 1``, lifted to the hemisphere as
``d = normalize(px, 1 − |px| − |py|, py)`` (glTF axes, +Y up). A shader finds the cells of a view
direction by the inverse: ``p = (dx, dz) / (|dx| + |dy| + |dz|)``, ``g = (px + py, px − py)``. Column
``i`` runs left to right, row ``j`` from the atlas's top.

Every view is orthographic, looking along ``−d`` at the centre of the tree's rest bounding sphere,
``2r`` wide: a cell's pixel ``(x, y)`` (from its top left) is the point
``c + r (2(x + ½)/S − 1) right − r (2(y + ½)/S − 1) up`` of the view's plane. Pure numpy: the
renders are Blender's (:mod:`operators.scene.impostor`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .axes import TO_GLTF

FILES = ("impostor_albedo.png", "impostor_normal.png", "impostor.json")


@dataclass
class ImpostorLayout:
    """``grid`` N cells a side, ``cell`` pixels a cell side; ``centre (3,)`` metres Blender axes and
    ``radius`` metres of the rest bounding sphere."""

    grid: int
    cell: int
    centre: np.ndarray
    radius: float

    @property
    def size(self) -> int:
        return self.grid * self.cell


def grid_directions(n: int) -> np.ndarray:
    """``(N, N, 3)`` unit view directions (glTF axes, towards the viewer), indexed ``[row j, column
    i]`` (module docstring)."""
    c = 2.0 * (np.arange(n) + 0.5) / n - 1.0
    gx, gy = np.meshgrid(c, c)                         # gx varies along columns (i), gy along rows (j)
    px, py = 0.5 * (gx + gy), 0.5 * (gx - gy)
    d = np.stack([px, 1.0 - np.abs(px) - np.abs(py), py], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def direction_cell(d: np.ndarray, n: int) -> np.ndarray:
    """``(..., 2)`` (column i, row j) of the cell whose grid point is nearest direction ``d (..., 3)``
    (glTF axes, upper hemisphere): the encoding the shader uses."""
    d = np.asarray(d, np.float64)
    p = d[..., [0, 2]] / np.abs(d).sum(axis=-1, keepdims=True)
    g = np.stack([p[..., 0] + p[..., 1], p[..., 0] - p[..., 1]], axis=-1)
    return np.clip(np.floor((g + 1.0) / 2.0 * n), 0, n - 1).astype(np.int64)


def view_basis(d_gltf: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(forward, right, up)`` unit vectors in Blender axes of the view looking along ``−d``
    (``d`` glTF axes towards the viewer): ``up`` the world up made perpendicular (for the zenith
    view, the world's −Y, glTF's +Z, points up the image)."""
    d = TO_GLTF.T @ np.asarray(d_gltf, np.float64)        # Blender axes
    forward = -d
    world_up = np.array([0.0, 0.0, 1.0])
    if abs(d @ world_up) > 0.999:
        world_up = np.array([0.0, 1.0, 0.0])
    right = np.cross(forward, world_up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    return forward, right, up


def layout_for(points: np.ndarray, grid: int = 8, cell: int = 128) -> ImpostorLayout:
    """The layout of a tree whose rest points (Blender axes, metres) are ``points (P, 3)``: the
    bounding box's centre and the farthest point from it."""
    p = np.asarray(points, np.float64)
    c = 0.5 * (p.min(0) + p.max(0))
    return ImpostorLayout(int(grid), int(cell), c, float(np.linalg.norm(p - c, axis=1).max() * 1.02))


def impostor_doc(layout: ImpostorLayout, tree_name: str) -> dict:
    """``impostor.json``: the layout, every cell's view direction, the bounds, the encodings."""
    d = grid_directions(layout.grid)
    return {
        "format": "tree_from_video.impostor", "version": 1, "tree": tree_name,
        "layout": "hemi-octahedral", "grid": layout.grid, "cell_px": layout.cell, "atlas_px": layout.size,
        "files": {"albedo": FILES[0], "normal": FILES[1]},
        "axes": "glTF: +Y up, right-handed, metres",
        "centre": np.round(TO_GLTF @ layout.centre, 5).tolist(), "radius": round(layout.radius, 5),
        "mapping": ("cell (i, j): g = (2(i+0.5)/N - 1, 2(j+0.5)/N - 1), column i left to right, row j from the "
                    "top; p = ((gx+gy)/2, (gx-gy)/2); view direction d = normalize(px, 1-|px|-|py|, py); inverse "
                    "p = (dx, dz)/(|dx|+|dy|+|dz|), g = (px+py, px-py)"),
        "view": ("orthographic along -d through centre, 2 radius wide; image up = world up made "
                 "perpendicular to d (for the zenith view, +Z)"),
        "albedo": "RGBA 8-bit sRGB, alpha the coverage (alpha-test at 0.5)",
        "normal": "RGB 8-bit linear, (n + 1) / 2 of the surface normal in glTF axes; A the coverage",
        "directions": np.round(d, 5).tolist(),
    }


def card_mesh(layout: ImpostorLayout, base_z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The crossed billboard: two vertical quads through the centre's vertical axis, one facing the
    front (Blender −Y, glTF +Z) and one the side (+X), each ``2r`` wide and from ``base_z`` to
    ``centre.z + r`` high, UVs on the atlas cells of those two directions (the horizon row nearest
    0° elevation). Returns ``co (8, 3)`` metres Blender axes, ``uv (8, 2)`` Blender (v up), and
    ``quads (2, 4)`` vertex indices."""
    c, r, n = layout.centre, layout.radius, layout.grid
    top = c[2] + r
    co, uv = [], []
    for d_gltf, along in ((np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])),       # front card, X across
                          (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))):      # side card, Y across
        # a horizon view: the cell nearest d lifted a hair (the hemisphere's rim)
        i, j = direction_cell(d_gltf + np.array([0.0, 1e-3, 0.0]), n)
        u0, u1 = i / n, (i + 1) / n
        v_top, v_bottom = 1.0 - j / n, 1.0 - (j + 1) / n                 # Blender's v runs up
        # the cell's image spans [c - r, c + r] across and vertically; the card from base_z to top
        frac = lambda z: (z - (c[2] - r)) / (2 * r)                      # noqa: E731  (height → cell v)
        _, right, _ = view_basis(d_gltf)
        sign = 1.0 if right @ along > 0 else -1.0
        a, b = c - sign * r * along, c + sign * r * along              # left, right edge as seen
        for p, u in ((a, u0), (b, u1)):
            for z in (base_z, top):
                co.append([p[0], p[1], z])
                uv.append([u, v_bottom + (v_top - v_bottom) * frac(z)])
    co_a = np.asarray(co, np.float32)
    # per card: (left bottom, left top, right bottom, right top) → quad 0, 2, 3, 1
    quads = np.array([[0, 2, 3, 1], [4, 6, 7, 5]], np.int32)
    return co_a, np.asarray(uv, np.float32), quads
