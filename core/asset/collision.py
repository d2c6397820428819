"""Collision capsules for game engines (issue 33, ``--collision``): the trunk and the main limbs as
capsules at rest, for Unreal's FBX convention (meshes named ``UCP_<tree>_NN``, each fitted to a
capsule on import) and listed in ``collision.json`` for any engine.

Which branches: the trunk and the limbs of the first fork level (:func:`.pivot_painter.
branch_elements` on the full rig: at a fork the heaviest child goes on) whose base is at least
:data:`MIN_RADIUS_SHARE` of the trunk's base radius. Each branch's chain of bones is cut into
pieces that stay within their capsule: a piece grows bone by bone while every joint of it lies
within ``MAX_BEND`` × its radius of the straight line from its start to its end. A capsule's
radius is the largest radius along its piece. At most :data:`MAX_CAPSULES`, thickest first.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .. import bones
from ..fileio import json_bytes, write_files
from ..tree3d import Tree3D
from .axes import TO_GLTF, TO_UNREAL
from .pivot_painter import branch_elements, element_bases
from .rig import Rig

MIN_RADIUS_SHARE = 0.45
MAX_BEND = 1.0
MAX_CAPSULES = 16
FILE = "collision.json"


@dataclass
class Capsule:
    """``a``, ``b`` ``(3,)`` the axis' ends, metres, Blender axes; ``radius`` metres; ``level`` 0
    trunk, 1 limb."""

    a: np.ndarray
    b: np.ndarray
    radius: float
    level: int


def _chain(rig: Rig, elem: np.ndarray, e: int, base: int) -> list[int]:
    """The bones of element ``e`` from its base along the stem (each step the child in ``e``)."""
    out = [base]
    children: dict[int, list[int]] = {}
    for b in np.flatnonzero(elem == e):
        children.setdefault(int(rig.parent[b]), []).append(int(b))
    while True:
        nxt = [c for c in children.get(out[-1], []) if c < rig.n_branch]
        if not nxt:
            return out
        out.append(nxt[0])


def capsules(tree: Tree3D, rig: Rig) -> list[Capsule]:
    """The capsules of the trunk and main limbs of ``tree`` (module docstring); ``rig`` the full
    rig (every branch bone: a bone budget's would lose the bends)."""
    B = rig.n_branch
    edges = bones.bone_edges(tree.parents)
    r_node = np.asarray(tree.radius, np.float64)
    radius = np.maximum(r_node[edges[:, 0]], r_node[edges[:, 1]])            # (B,) a bone's thicker end
    elem, _, level = branch_elements(rig)
    base = element_bases(rig, elem, len(level))
    trunk_r = float(radius[base[level == 0]].max()) if (level == 0).any() else float(radius.max())
    out: list[Capsule] = []
    for e in np.flatnonzero(level <= 1):
        if base[e] >= B or radius[base[e]] < MIN_RADIUS_SHARE * trunk_r:
            continue
        chain = _chain(rig, elem, int(e), int(base[e]))
        start = 0
        while start < len(chain):
            end = start
            while end + 1 < len(chain):
                seg = chain[start:end + 2]
                a, b = rig.head[seg[0]].astype(np.float64), rig.tail[seg[-1]].astype(np.float64)
                pts = rig.tail[seg[:-1]].astype(np.float64)
                d = b - a
                t = np.clip((pts - a) @ d / max(float(d @ d), 1e-12), 0, 1)
                off = np.linalg.norm(pts - (a + t[:, None] * d), axis=1)
                if (off > MAX_BEND * radius[seg].max()).any():
                    break
                end += 1
            seg = chain[start:end + 1]
            out.append(Capsule(rig.head[seg[0]].astype(np.float64), rig.tail[seg[-1]].astype(np.float64),
                               float(radius[seg].max()), int(level[e])))
            start = end + 1
    out.sort(key=lambda c: -c.radius)
    return out[:MAX_CAPSULES]


def capsule_mesh(c: Capsule, sides: int = 8, rings: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A closed capsule mesh: ``co (V, 3)`` metres, ``loop_vert``, ``loop_total (P,)`` (quads, and
    an S-gon closing each pole: the poles are rings at 95° of latitude, not points)."""
    axis = c.b - c.a
    length = float(np.linalg.norm(axis))
    y = axis / max(length, 1e-12)
    ref = np.array([0.0, 0.0, 1.0]) if abs(y[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(y, ref)
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    th = 2 * np.pi * np.arange(sides) / sides
    # latitudes: the bottom cap (−90°..0) at a, the top cap (0..90°) at b
    lat = np.concatenate([np.linspace(-np.pi / 2 * 0.95, 0, rings + 1), np.linspace(0, np.pi / 2 * 0.95, rings + 1)])
    centre = np.concatenate([np.repeat(c.a[None], rings + 1, 0), np.repeat(c.b[None], rings + 1, 0)])
    ring = np.cos(th)[:, None] * x + np.sin(th)[:, None] * z                      # (S, 3)
    co = (centre[:, None] + c.radius * (np.cos(lat)[:, None, None] * ring[None]
                                        + np.sin(lat)[:, None, None] * y[None, None])).reshape(-1, 3)
    L = len(lat)
    k = np.arange(sides)
    kn = (k + 1) % sides
    j = np.arange(L - 1)[:, None]
    quads = np.stack([j * sides + k, j * sides + kn, (j + 1) * sides + kn, (j + 1) * sides + k], -1).reshape(-1, 4)
    caps = np.array([k[::-1], (L - 1) * sides + k])                               # two S-gons closing the poles
    return co, np.concatenate([quads.ravel(), caps.ravel()]), np.concatenate([np.full(len(quads), 4), [sides, sides]])


def collision_doc(tree_name: str, caps: list[Capsule]) -> dict:
    """``collision.json``: each capsule's name, ends and radius in metres (Blender and glTF axes)
    and centimetres (Unreal axes)."""
    items = []
    for k, c in enumerate(caps):
        items.append({"name": capsule_name(tree_name, k), "level": c.level, "radius_m": round(c.radius, 5),
                      "a_m": np.round(c.a @ TO_GLTF.T, 5).tolist(), "b_m": np.round(c.b @ TO_GLTF.T, 5).tolist(),
                      "radius_cm": round(100 * c.radius, 3), "a_cm": np.round(c.a @ TO_UNREAL.T, 3).tolist(),
                      "b_cm": np.round(c.b @ TO_UNREAL.T, 3).tolist()})
    return {"format": "tree_from_video.collision", "version": 1, "tree": tree_name, "capsules": items,
            "axes": {"*_m": "glTF: +Y up, right-handed, metres", "*_cm": "Unreal: (x, -y, z), centimetres"},
            "shape": "capsule: the segment a-b swept by the radius (rest pose; the tree's base at the origin)"}


def capsule_name(tree_name: str, k: int) -> str:
    """``UCP_<tree>_NN`` (spaces as underscores: Unreal matches the name)."""
    return f"UCP_{tree_name.replace(' ', '_')}_{k:02d}"


def collision_files(tree_name: str, caps: list[Capsule]) -> dict[str, bytes]:
    return {FILE: json_bytes(collision_doc(tree_name, caps))}


def write_collision(folder: str | os.PathLike, tree_name: str, caps: list[Capsule]) -> str:
    return write_files(folder, collision_files(tree_name, caps))[0]
