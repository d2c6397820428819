"""The animated 3D tree handed from the core to Blender and to files.

World axes follow Blender's front view: x right, y away from the camera (depth), z up, origin at
the trunk base. The core lifts and animates in pixels of frame 1 (:func:`image_to_plane`); the
tree is then scaled to metres so it stands ``height_m`` tall.
"""
from __future__ import annotations

import io
import json
import os
from dataclasses import dataclass, field

import numpy as np

from .fileio import atomic_savez
from .meta import TreeMeta

FORMAT = "tree_from_video.tree3d"
VERSION = 1


@dataclass
class LeafClusters:
    """Leaf clusters riding on the tree's bones (built by :mod:`.detail.leaf_seeds` and :mod:`.detail.leaf_clusters`).

    ``node (S,)`` int32 tree node whose bone carries the cluster (the bone into that node; the
    root's first child for node 0); ``pos (S, 3)`` float32 cluster centre at rest (tree frame 0),
    metres; ``axis (S, 3)`` unit outward direction from the crown (the cluster's main axis);
    ``colour (S, 3)`` float32 sRGB 0..1 sampled from the video at the seed; ``dark (S,)`` bool
    (seed from the shaded half: behind the branches); ``flutter (F, S)`` float32 radians about
    ``axis`` per frame, ``A(t) sin(ωt + β)``; ``radius`` metres of one cluster; ``leaf_size``
    metres of one leaf card's length; ``cards`` leaf cards per cluster; ``seed`` of the template;
    ``scale (S,)`` each cluster's size relative to ``radius`` (smaller near the outline's edge);
    ``leaf_hz``, ``leaf_angle`` (radians): every leaf's own high-frequency flap about its stem,
    ``leaf_angle · sin(2π leaf_hz t + φ_leaf)`` (:func:`.detail.leaf_clusters.leaf_flap_offsets`);
    ``shape`` ``"cluster"`` (cards round the centre), ``"frond"`` (a palm's leaflets in pairs
    along the axis, :func:`.detail.leaf_clusters.frond_template`) or ``"spray"`` (a conifer's
    needle sprays spreading level, :func:`.detail.leaf_clusters.spray_template`); ``flutter_hz`` ω / 2π of the
    flutter (0: not recorded, a file from before it was)."""

    node: np.ndarray
    pos: np.ndarray
    axis: np.ndarray
    colour: np.ndarray
    dark: np.ndarray
    flutter: np.ndarray
    radius: float
    leaf_size: float
    cards: int
    seed: int = 0
    scale: np.ndarray | None = None
    leaf_hz: float = 4.0
    leaf_angle: float = 0.26
    shape: str = "cluster"
    flutter_hz: float = 0.0

    def scales(self) -> np.ndarray:
        """``(S,)`` size of each cluster relative to ``radius`` (1 when not set)."""
        return np.ones(len(self.node), np.float32) if self.scale is None else np.asarray(self.scale, np.float32)

    @property
    def count(self) -> int:
        return len(self.node)

    @property
    def polygons(self) -> int:
        """One quad per leaf card."""
        return self.count * int(self.cards)


LEAF_ARRAYS = ("node", "pos", "axis", "colour", "dark", "flutter", "scale")


@dataclass
class Tree3D:
    """``parents (N,)`` int32 (-1 root = trunk base, node 0); ``nodes3d (F, N, 3)`` float32 metres
    for every frame; ``radius (N,)`` float32 metres (branch radius at each node); ``level (N,)``
    int32 branching order; ``fps`` frames per second; ``name`` shown in Blender; ``times (F,)``
    seconds from the first frame where the video's frames are unevenly spaced (None: ``index / fps``;
    :func:`key_frames`)."""

    parents: np.ndarray
    nodes3d: np.ndarray
    radius: np.ndarray
    level: np.ndarray
    fps: float
    name: str = "Tree"
    meta: TreeMeta = field(default_factory=lambda: TreeMeta())   # keys: :mod:`.meta`
    leaves: LeafClusters | None = None
    times: np.ndarray | None = None

    @property
    def n_nodes(self) -> int:
        return len(self.parents)

    @property
    def n_frames(self) -> int:
        return self.nodes3d.shape[0]

    def edges(self) -> np.ndarray:
        """``(N-1, 2)`` (parent, child) pairs: one bone per edge, named after the child node."""
        from .topology import edges_of
        return edges_of(self.parents)


def uneven_times(times: np.ndarray | None, fps: float) -> np.ndarray | None:
    """``times (F,)`` seconds when they stray from ``index / fps`` by more than 5 % of a frame
    interval somewhere (a variable frame rate), else None (evenly spaced: keys at whole frames)."""
    if times is None or len(times) < 2:
        return None
    t = np.asarray(times, np.float64)
    even = np.arange(len(t)) / float(fps)
    return t if np.abs(t - t[0] - even).max() > 0.05 / float(fps) else None


def key_frames(tree: Tree3D) -> np.ndarray:
    """``(F,)`` float32 scene frames of the tree's keys: ``1 + t · fps`` at the frames' times (so a
    variable-frame-rate clip keeps its timing, on subframes), or ``1..F``."""
    if tree.times is None:
        return np.arange(1, tree.n_frames + 1, dtype=np.float32)
    t = np.asarray(tree.times, np.float64)
    return (1.0 + (t - t[0]) * float(tree.fps)).astype(np.float32)


def last_key_frame(tree: Tree3D) -> int:
    """The scene frame the tree's last key falls on or before (its animation's length in frames)."""
    return max(tree.n_frames, int(np.ceil(float(key_frames(tree)[-1]) - 1e-6)))


def pipe_radii(parents: np.ndarray, tip_radius: float, exponent: float = 2.0,
               fixed: np.ndarray | None = None) -> np.ndarray:
    """Pipe-model radii: tips get ``tip_radius``; ``r_parent^e = Σ r_child^e`` (e ≈ 2), and a node
    on a chain (one child) keeps its child's radius. ``fixed (N,)`` metres (nan: free): those
    nodes keep their radius and pass it on in place of what hangs below them (a placed cut's).
    Returns ``(N,)``."""
    from .topology import topological_order
    r = np.zeros(len(parents))
    has_child = np.zeros(len(parents), bool)
    has_child[parents[parents >= 0]] = True
    r[~has_child] = tip_radius ** exponent
    acc = np.where(has_child, 0.0, r)
    hold = np.zeros(len(parents), bool) if fixed is None else np.isfinite(fixed)
    for n in topological_order(parents)[::-1]:       # leaves first
        if hold[n]:
            acc[n] = float(fixed[n]) ** exponent     # type: ignore[index]
        p = parents[n]
        if p >= 0:
            acc[p] += acc[n]
    return (acc ** (1.0 / exponent)).astype(np.float32)


def image_to_plane(xy_px: np.ndarray, base_px: np.ndarray) -> np.ndarray:
    """Image pixels ``(..., 2)`` (x right, y down) → points ``(..., 3)`` in the plane through the
    trunk: x right and z up in pixels from the trunk base, depth y = 0."""
    out = np.zeros(xy_px.shape[:-1] + (3,), np.float64)
    out[..., 0] = xy_px[..., 0] - base_px[0]
    out[..., 2] = base_px[1] - xy_px[..., 1]
    return out


def plane_to_image(p: np.ndarray, base_px: np.ndarray) -> np.ndarray:
    """Orthographic projection along depth: points ``(..., 3)`` (px from the base) → image px ``(..., 2)``."""
    return np.stack([p[..., 0] + base_px[0], base_px[1] - p[..., 2]], axis=-1)


def _arrays(tree: Tree3D) -> dict:
    """The arrays of a tree file (:func:`save_tree`): nodes, radii, levels, fps, JSON metadata, leaves."""
    meta = {"format": FORMAT, "version": VERSION, "name": tree.name, **tree.meta}
    extra = {}
    if tree.leaves is not None:
        lv = tree.leaves
        meta["leaves"] = {"radius": float(lv.radius), "leaf_size": float(lv.leaf_size),
                          "cards": int(lv.cards), "seed": int(lv.seed), "leaf_hz": float(lv.leaf_hz),
                          "leaf_angle": float(lv.leaf_angle), "shape": str(lv.shape),
                          "flutter_hz": float(lv.flutter_hz)}
        extra = {f"leaf_{k}": np.asarray(getattr(lv, k) if k != "scale" else lv.scales())
                 for k in LEAF_ARRAYS}
    return dict(parents=tree.parents.astype(np.int32), nodes3d=tree.nodes3d.astype(np.float32),
                radius=tree.radius.astype(np.float32), level=tree.level.astype(np.int32),
                fps=np.float64(tree.fps), meta_json=np.array(json.dumps(meta)), **extra,
                **({} if tree.times is None else {"times": np.asarray(tree.times, np.float64)}))


def save_tree(path: str | os.PathLike, tree: Tree3D) -> None:
    """Write ``tree`` as ``.npz`` (arrays + JSON metadata), atomically; no pickle."""
    atomic_savez(path, **_arrays(tree))


def tree_bytes(tree: Tree3D) -> bytes:
    """``tree`` as the bytes of an uncompressed ``.npz``, the format :func:`save_tree` writes (what
    Blender keeps with a tree in the .blend); :func:`tree_from_bytes` reads it back exactly."""
    buf = io.BytesIO()
    np.savez(buf, **_arrays(tree))
    return buf.getvalue()


def tree_from_bytes(data: bytes, what: str = "the stored tree") -> Tree3D:
    """The tree in ``data`` written by :func:`tree_bytes` (or the bytes of a tree ``.npz``)."""
    return _read(io.BytesIO(data), what)


def load_tree(path: str | os.PathLike) -> Tree3D:
    return _read(os.fspath(path), f"'{path}'")


def _read(source, what: str) -> Tree3D:
    with np.load(source, allow_pickle=False) as z:
        meta = json.loads(str(z["meta_json"]))
        if meta.get("format") != FORMAT:
            from .errors import InputError
            raise InputError(f"{what} is not a Tree from Video 3D tree file")
        name = meta.pop("name", "Tree")
        leaves = None
        info = meta.pop("leaves", None)
        if info is not None and "leaf_node" in z.files:
            arrays = {k: z[f"leaf_{k}"] for k in LEAF_ARRAYS if f"leaf_{k}" in z.files}
            leaves = LeafClusters(**arrays, **info)
        return Tree3D(z["parents"].astype(np.int32), z["nodes3d"].astype(np.float32),
                      z["radius"].astype(np.float32), z["level"].astype(np.int32), float(z["fps"]),
                      name, meta, leaves, z["times"].astype(np.float64) if "times" in z.files else None)
