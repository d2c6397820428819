"""3D trees for the scene and export tests, and reading poses back out of Blender."""
from __future__ import annotations

import os

import numpy as np
import pytest

from tree_from_video.core import bones
from tree_from_video.core.tree3d import Tree3D

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: metres per pixel of the synthetic ground truth (its 288 px tree becomes 8.6 m tall)
SCALE = 0.03


def broad_tree(frames: int | None = 60) -> Tree3D:
    """The committed ``broad`` sample's ground truth (235 nodes, 180 frames, 24 fps) in metres.

    ``truth.npz`` has x right, y depth, z up in pixels (1 unit = 1 px) with the trunk base at the
    origin (image ``(cx, ground_v)``); here it is scaled by :data:`SCALE` and the frame-0 base is
    moved to the origin explicitly."""
    with np.load(os.path.join(ROOT, "sample_videos", "broad", "truth.npz")) as z:
        nodes = z["nodes3d"].astype(np.float64)
        if frames is not None:
            nodes = nodes[:frames]
        nodes = (nodes - nodes[0, 0]) * SCALE
        return Tree3D(z["parents"].astype(np.int32), nodes.astype(np.float32),
                      (z["radius"] * SCALE).astype(np.float32), z["depth_level"].astype(np.int32),
                      float(z["fps"]), "Broad")


def binary_tree(n_bones: int = 127, frames: int = 300, fps: float = 30.0, seed: int = 0) -> Tree3D:
    """A swaying tree of ``n_bones`` bones: a trunk bone, then binary branching (node ``k`` ≥ 2 is a
    child of ``k // 2``). Each edge sways about its own axis, so lengths stay exact."""
    rng = np.random.default_rng(seed)
    n = n_bones + 1
    parents = np.array([-1, 0] + [k // 2 for k in range(2, n)], np.int32)
    depth = np.zeros(n, int)
    for k in range(1, n):
        depth[k] = depth[parents[k]] + 1
    spread = rng.uniform(0.3, 0.8, n) * np.where(np.arange(n) % 2, 1, -1)
    yaw = rng.uniform(0, 2 * np.pi, n)
    offset = np.stack([np.sin(spread) * np.cos(yaw), np.sin(spread) * np.sin(yaw), np.cos(spread)], 1)
    offset[1] = [0, 0, 1]
    offset *= (1.5 * 0.8 ** depth)[:, None]
    t = np.arange(frames) / fps
    angle = 0.15 * np.sin(2 * np.pi * rng.uniform(0.3, 1.2, n)[None] * t[:, None] + rng.uniform(0, 6, n))
    axis = np.cross(offset, [1.0, 0.3, 0.0])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    nodes = np.zeros((frames, n, 3))
    for k in range(1, n):                                  # parents come first
        c, s = np.cos(angle[:, k])[:, None], np.sin(angle[:, k])[:, None]
        v, a = offset[k], axis[k]
        rotated = v * c + np.cross(a, v) * s + a * (a @ v) * (1 - c)  # Rodrigues
        nodes[:, k] = nodes[:, parents[k]] + rotated
    radius = np.full(n, 0.02) + 0.1 * 0.7 ** depth
    return Tree3D(parents, nodes.astype(np.float32), radius.astype(np.float32), depth.astype(np.int32),
                  fps, "Binary")


def rig_rest(rig, tree: Tree3D) -> np.ndarray:
    """``(B, 3, 3)`` the rest rotations of the built rig's branch bones, in the tree's bone order."""
    flat = np.empty(len(rig.data.bones) * 16, np.float32)
    rig.data.bones.foreach_get("matrix_local", flat)
    mats = flat.reshape(-1, 4, 4).transpose(0, 2, 1)
    order = {b.name: i for i, b in enumerate(rig.data.bones)}
    return mats[[order[n] for n in bones.bone_names(tree.parents)], :3, :3].astype(np.float64)


def tree_height(tree: Tree3D) -> float:
    """Height (m) of frame 0: the tolerance scale."""
    return float(np.ptp(tree.nodes3d[0][:, 2]))


def pose_tails(rig, names) -> np.ndarray:
    """World positions ``(B, 3)`` of the pose bones' tails at the evaluated frame."""
    mw = np.array(rig.matrix_world)
    t = np.array([rig.pose.bones[n].tail for n in names], np.float64)
    return t @ mw[:3, :3].T + mw[:3, 3]


def pose_heads_dirs(rig, names) -> tuple[np.ndarray, np.ndarray]:
    """World heads ``(B, 3)`` and unit Y axes (bone directions) ``(B, 3)`` of the pose bones."""
    mw = np.array(rig.matrix_world)
    h = np.array([rig.pose.bones[n].head for n in names], np.float64) @ mw[:3, :3].T + mw[:3, 3]
    y = np.array([np.array(rig.pose.bones[n].matrix)[:3, 1] for n in names]) @ mw[:3, :3].T
    return h, y / np.linalg.norm(y, axis=1, keepdims=True)


def played(rig, names, frames) -> dict:
    """What the built ``rig`` plays (its curves: reduced keys, samples, cycles) at each scene frame
    of ``frames``: ``{frame: (heads, tails, dirs)}`` in world space — what an export must carry."""
    import bpy
    out = {}
    for k in frames:
        bpy.context.scene.frame_set(k)
        heads, dirs = pose_heads_dirs(rig, names)
        out[k] = (heads, pose_tails(rig, names), dirs)
    return out


def expected(tree: Tree3D, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heads, tails ``(B, 3)`` and unit directions of the bones at scene frame ``frame`` (1-based)."""
    edges = bones.bone_edges(tree.parents)
    p = tree.nodes3d[frame - 1].astype(np.float64)
    d = p[edges[:, 1]] - p[edges[:, 0]]
    return p[edges[:, 0]], p[edges[:, 1]], d / np.linalg.norm(d, axis=1, keepdims=True)


def assert_closed_tubes(me) -> np.ndarray:
    """Every edge of the mesh ``me`` has two faces (closed), and every connected piece (a tree's
    joined tubes, or a tube of its own) encloses a positive volume (normals point out). Returns the
    vertices ``(V, 3)``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    edge_index = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("edge_index", edge_index)
    assert (np.bincount(edge_index, minlength=len(me.edges)) == 2).all()     # every edge has 2 faces
    me.calc_loop_triangles()
    tri = np.empty(len(me.loop_triangles) * 3, np.int32)
    me.loop_triangles.foreach_get("vertices", tri)
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    ev = np.empty(len(me.edges) * 2, np.int32)
    me.edges.foreach_get("vertices", ev)
    ev = ev.reshape(-1, 2)
    V = len(me.vertices)
    _, piece = connected_components(coo_matrix((np.ones(len(ev)), (ev[:, 0], ev[:, 1])), shape=(V, V)), directed=False)
    a, b, c = co.reshape(-1, 3)[tri.reshape(-1, 3)].astype(np.float64).transpose(1, 0, 2)
    vol = np.bincount(piece[tri.reshape(-1, 3)[:, 0]], np.einsum("ij,ij->i", a, np.cross(b, c)) / 6)
    used = np.unique(piece[tri])
    assert (vol[used] > 0).all(), "a piece is inside out"
    return co.reshape(-1, 3)


@pytest.fixture(autouse=True)
def empty_scene():
    """Every Blender test starts and ends in an empty factory scene (import it into the module)."""
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield
    bpy.ops.wm.read_factory_settings(use_empty=True)


@pytest.fixture(autouse=True, scope="module")
def registered():
    """The add-on registered once for a module's tests (import it into the module, with
    :func:`empty_scene` for an empty scene per test)."""
    import tree_from_video as pkg
    pkg.register()
    yield
    pkg.unregister()


@pytest.fixture(autouse=True)
def addon():
    """The add-on registered in an empty factory scene for each test; yields ``scene.tree_video``
    (import it into the module, like :func:`empty_scene`)."""
    import bpy

    import tree_from_video
    bpy.ops.wm.read_factory_settings(use_empty=True)
    tree_from_video.register()
    yield bpy.context.scene.tree_video
    tree_from_video.unregister()
    bpy.ops.wm.read_factory_settings(use_empty=True)
