"""The measured motion as a bone-animation texture (issue 33, ``--bone-texture``): for any engine
that skins in a vertex shader (the web viewer, Unity/Unreal/Godot materials), one row per frame
and two texels per bone, in a half-float EXR with a JSON sidecar.

Encoding (``bone_anim.json`` repeats it): texel ``2k`` of row ``f`` holds ``t_k(f)``, the
displacement of bone ``k``'s head from its bind position (RGB, metres; A = 1); texel ``2k + 1``
holds ``q_k(f)``, the bone's rotation from its bind pose (x, y, z, w), both in model space. A
vertex ``p`` (bind pose) carried by bone ``k`` plays at

    x(f) = h_k + t_k(f) + q_k(f) (p − h_k)                                   (h_k the bind head)

which is the skinning matrix ``W_k(f)`` of the rig (``W_k = P_k M_k⁻¹``, Blender's pose composed
from the keys) written as a turn about the bone's head: the head's displacement stays small (cm),
so half floats keep it to a fraction of a millimetre, and a unit quaternion's components keep
11 bits. Rows are frames 0..F−1 from the image's top (a loop's closing frame, equal to its first,
is not repeated: the shader wraps). Axes are glTF's (+Y up, right-handed: Blender's
``(x, y, z)`` → ``(x, z, −y)``), the axes of the GLB whose skin joints the bones name.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .. import bones
from ..fileio import json_bytes, write_files
from ..rotations import make_continuous, matrix_to_quat, quat_to_matrix
from ..tree3d import Tree3D
from .axes import TO_GLTF
from .budget import world_motion
from .exr import exr_bytes
from .rig import Rig

FILES = ("bone_anim.exr", "bone_anim.json")


@dataclass
class BoneTexture:
    """``pixels (F, 2K, 4)`` float32 (row f = frame f), ``doc`` the sidecar's content."""

    pixels: np.ndarray
    doc: dict


def rig_world(tree: Tree3D, rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """Every bone's skinning transform per frame, as ``q (F, K, 4)`` rotation from rest and ``head
    (F, K, 3)`` metres (a point ``p`` of bone ``k`` at ``head_k + q_k (p − head_k⁰)``), Blender's
    axes. A full rig (bones that only turn, leaf bones with their flutter) from the tree's motion
    (:func:`.budget.world_motion`); a rig with location keys (a bone budget's) composed the way
    Blender composes pose bones, ``P_k = P_parent (M_parent⁻¹ M_k) B_k``, ``W_k = P_k M_k⁻¹``."""
    if rig.keys.location is None:
        return world_motion(tree, rig)
    K = len(rig.names)
    M = np.tile(np.eye(4), (K, 1, 1))
    M[:, :3, :3], M[:, :3, 3] = rig.rest, rig.head
    F = len(rig.keys.local)
    Bk = np.tile(np.eye(4), (F, K, 1, 1))
    Bk[..., :3, :3] = quat_to_matrix(rig.keys.local)
    Bk[..., :3, 3] = rig.keys.location
    rel = M.copy()
    has = rig.parent >= 0
    rel[has] = np.linalg.inv(M[rig.parent[has]]) @ M[has]
    P = np.empty((F, K, 4, 4))
    depth = bones.bone_depths(rig.parent)
    for d in range(int(depth.max()) + 1 if K else 0):       # one depth at a time, parents first
        at = np.flatnonzero(depth == d)
        base = rel[at][None] if d == 0 else P[:, rig.parent[at]] @ rel[at][None]
        P[:, at] = base @ Bk[:, at]
    W = P @ np.linalg.inv(M)[None]
    head0 = rig.head.astype(np.float64)
    heads = np.einsum("fkij,kj->fki", W[..., :3, :3], head0) + W[..., :3, 3]
    return matrix_to_quat(W[..., :3, :3]), heads


def bone_texture(tree: Tree3D, rig: Rig) -> BoneTexture:
    """The texture and sidecar of ``rig``'s motion (module docstring); ``tree`` the tree the rig was
    made from (its fps, its loop flag)."""
    q, heads = rig_world(tree, rig)
    loop = bool(tree.meta.get("loop"))
    if loop and len(q) > 1:                     # the closing frame repeats the first: the shader wraps
        q, heads = q[:-1], heads[:-1]
    q = make_continuous(q / np.linalg.norm(q, axis=-1, keepdims=True))
    h0 = rig.head.astype(np.float64)
    t = (heads - h0[None]) @ TO_GLTF.T
    v = q[..., 1:] @ TO_GLTF.T
    F, K = q.shape[:2]
    px = np.empty((F, 2 * K, 4), np.float32)
    px[:, 0::2, :3] = t
    px[:, 0::2, 3] = 1.0
    px[:, 1::2, :3] = v
    px[:, 1::2, 3] = q[..., 0]
    doc = {
        "format": "tree_from_video.bone_anim", "version": 1, "image": FILES[0],
        "width": 2 * K, "height": F, "pixel_type": "half float RGBA, OpenEXR, no compression",
        "encoding": ("row f (from the image's top) is frame f; texel 2k: RGB the displacement t of bone k's "
                     "head from its bind position, A = 1; texel 2k+1: the bone's rotation q from its bind "
                     "pose as a quaternion (x, y, z, w); a vertex p (bind pose) of bone k plays at "
                     "h_k + t + q (p - h_k), h_k = bind_heads[k]"),
        "units": "m", "axes": "glTF: +Y up, +Z forward, right-handed (Blender (x, y, z) -> (x, z, -y))",
        "fps": float(tree.fps), "frame_count": int(F), "loop": loop, "duration_s": float(F / tree.fps),
        "bones": list(rig.names), "parents": [int(p) for p in rig.parent],
        "bind_heads": np.round(h0 @ TO_GLTF.T, 6).tolist(),
        "bind_tails": np.round(rig.tail.astype(np.float64) @ TO_GLTF.T, 6).tolist(),
        "joints": "a vertex's bone is its glTF skin joint of the same name (JOINTS_0/WEIGHTS_0 as in the GLB)",
    }
    return BoneTexture(px, doc)


def bone_files(tex: BoneTexture) -> dict[str, bytes]:
    """The file contents by name (:func:`.engine_files.with_prefix` renames them, the JSON's
    ``image`` too)."""
    return {FILES[0]: exr_bytes(tex.pixels), FILES[1]: json_bytes(tex.doc)}


def write_bone_texture(folder: str | os.PathLike, tex: BoneTexture) -> list[str]:
    """``bone_anim.exr`` and ``bone_anim.json`` in ``folder``, atomically; returns their paths."""
    return write_files(folder, bone_files(tex))
