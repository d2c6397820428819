"""Unreal Pivot Painter 2 (issue 33, ``--pivot-painter``): the rig's branches as PP2 elements, in
the two textures Epic's ``PivotPainter2FoliageShader`` reads, and each vertex's element in the
mesh's second UV channel.

Epic's layout (Pivot Painter Tool 2.0 and its MAXScript reference, dev.epicgames.com):

* ``pivot_pos_index.exr``, 16-bit float: RGB the element's pivot in Unreal's axes and centimetres
  (Blender ``(x, y, z)`` m → ``(x, −y, z)`` × 100); A its parent's index as "Int as float", the bit
  pattern of a half float holding ``index + 1024`` (``ms_PivotPainter2_UnpackIntegerAsFloat``
  undoes it; the +1024 keeps the exponent non-zero); a root points at itself.
* ``xaxis_extent.png``, 8-bit: RGB the element's X axis (unit, Unreal axes) packed ``(v + 1) / 2``;
  A its extent along X as ``clamp(cm / 8, 1, 256) / 256`` (8–2048 cm in 8 cm steps; decoded as
  ``A · 2048``).
* Element ``i`` sits at column ``i mod W``, row ``i div W`` from the image's top; a vertex's UV 1 is
  its element's pixel centre, ``u = (col + ½) / W``, ``v = 1 − (row + ½) / H`` in Blender's
  bottom-up UVs (Unreal's importer flips V, which lands on the row from the top).

Elements are **branches**, not bones: at a fork the child bone carrying the most bones continues its
parent's element (the stem goes on), the others start their own a level deeper. PP2's stock
shader walks 4 hierarchy levels; a game rig's bone chains are far deeper (the broad sample at 64
bones: bone depth 18, branch depth 4), so per bone the trunk alone would use the 4 levels. Elements
deeper than level 3 attach to their level-3 ancestor. At most 30,000 elements.

PP2 carries static pivots only: the measured motion reaches the PP2 wind material as parameters per
level fitted to it (``pivot_painter.json``): each level's RMS swing amplitude (degrees), its
dominant frequency (Hz, the peak of the swing angle's spectrum summed over the level's elements)
and the spread of its elements' phases at that frequency (radians, circular standard deviation).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .. import bones
from ..fileio import json_bytes, write_files
from ..rotations import quat_conj, quat_log, quat_mul
from ..tree3d import Tree3D
from .axes import TO_UNREAL
from .exr import exr_bytes
from .rig import Rig

LEVELS = 4
MAX_ELEMENTS = 30000
FILES = ("pivot_pos_index.exr", "xaxis_extent.png", "pivot_painter.json")


@dataclass
class PivotPainter:
    """``element_of_bone (K,)`` each rig bone's element; ``parent (E,)`` each element's parent
    element (a root itself); ``level (E,)`` 0..3; ``pivot (E, 3)`` cm Unreal axes; ``xaxis (E,
    3)`` unit, Unreal axes; ``extent (E,)`` cm; ``width``, ``height`` of the textures; ``doc`` the
    JSON (layout and the wind parameters per level)."""

    element_of_bone: np.ndarray
    parent: np.ndarray
    level: np.ndarray
    pivot: np.ndarray
    xaxis: np.ndarray
    extent: np.ndarray
    width: int
    height: int
    doc: dict

    def uv(self, bone: np.ndarray) -> np.ndarray:
        """``(V, 2)`` Blender UVs of the pixel centres of the elements of bones ``bone (V,)``."""
        e = self.element_of_bone[np.asarray(bone, np.int64)]
        col, row = e % self.width, e // self.width
        return np.stack([(col + 0.5) / self.width, 1.0 - (row + 0.5) / self.height], axis=1).astype(np.float32)


def int_as_float(n: np.ndarray) -> np.ndarray:
    """Epic's "Int as float": the half whose bit pattern is ``n + 1024`` (float16)."""
    n = np.asarray(n, np.int64)
    if (n < 0).any() or (n + 1024 >= 0x7C00).any():
        raise ValueError("an index must be 0..30719 to pack as a half float")
    return (n + 1024).astype(np.uint16).view(np.float16)


def branch_elements(rig: Rig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(element_of_bone (K,), parent (E,), level (E,))``: a bone continues its parent's element when
    it is the child carrying the most bones (the stem going on), else starts one a level deeper
    (module docstring); elements deeper than level ``LEVELS − 1`` merged into their parent element.
    Elements numbered root to tips."""
    K = len(rig.names)
    par = rig.parent.astype(np.int64)
    depth = bones.bone_depths(par)
    # the subtree each bone carries (bones), deepest first up to the roots
    size = np.ones(K, np.int64)
    for d in range(int(depth.max()) if K else 0, 0, -1):
        at = np.flatnonzero(depth == d)
        np.add.at(size, par[at], size[at])
    # at a fork the child carrying the most bones continues its parent's element (the stem goes on;
    # ties: the lower index), the others start their own
    leaf = np.arange(K) >= rig.n_branch                          # leaf-cluster bones ride their branch's element
    has = np.flatnonzero((par >= 0) & ~leaf)
    heavy = np.full(K, -1)
    order_h = has[np.lexsort((-has, size[has]))]                 # ascending size: the last write wins
    heavy[par[order_h]] = order_h
    starts = ((par < 0) | (heavy[np.maximum(par, 0)] != np.arange(K))) & ~leaf
    order = np.argsort(depth, kind="stable")                     # parents before children
    elem = np.full(K, -1)
    e_parent: list[int] = []
    e_level: list[int] = []
    for d in range(int(depth.max()) + 1 if K else 0):            # one bone depth at a time
        at = order[depth[order] == d]
        cont = at[~starts[at]]
        elem[cont] = elem[par[cont]]
        new = at[starts[at]]
        for b in new:                                            # forks: a few per depth
            p = par[b]
            pe = elem[p] if p >= 0 else -1
            lvl = 0 if pe < 0 else e_level[pe] + 1
            if lvl >= LEVELS:
                elem[b] = pe                                     # deeper than level 3: its parent's
                continue
            elem[b] = len(e_parent)
            e_parent.append(pe if pe >= 0 else elem[b])
            e_level.append(lvl)
    # a merged deep element's bones belong to their level-3 ancestor: already, by the rule above
    return elem.astype(np.int32), np.asarray(e_parent, np.int32), np.asarray(e_level, np.int8)


def element_bases(rig: Rig, elem: np.ndarray, E: int) -> np.ndarray:
    """``(E,)`` each element's first bone: the one of least depth among its bones (the bone that
    started it; bone indices need not run root to tips)."""
    depth = bones.bone_depths(rig.parent)
    order = np.lexsort((np.arange(len(elem)), depth))            # shallowest first
    base = np.full(E, -1)
    rev = order[::-1]                                             # the last write wins: the shallowest
    base[elem[rev]] = rev
    return base.astype(np.int64)


def wind_levels(rig: Rig, elem: np.ndarray, level: np.ndarray, fps: float) -> list[dict]:
    """Per level: ``amplitude_deg`` (RMS of the swing angle from each element's first bone's mean
    rotation, × √2: a sine's amplitude), ``frequency_hz`` (the peak of the summed spectra above
    0 Hz), ``phase_spread_rad`` (circular standard deviation of the elements' phases there)."""
    local = rig.keys.local
    first = element_bases(rig, elem, len(level))
    q = local[:, first]
    mean = q.mean(axis=0)
    mean /= np.maximum(np.linalg.norm(mean, axis=-1, keepdims=True), 1e-12)
    w = quat_log(quat_mul(quat_conj(mean)[None], q))             # (F, E, 3) rotation vectors
    # the swing signal: the rotation vector along each element's main swing direction
    F = len(q)
    out = []
    for lv in range(LEVELS):
        sel = np.flatnonzero(level == lv)
        if not len(sel) or F < 4:
            continue
        ws = w[:, sel]
        _, _, vt = np.linalg.svd(ws.transpose(1, 0, 2), full_matrices=False)
        swing = np.einsum("fei,ei->fe", ws, vt[:, 0])             # (F, e)
        swing = swing - swing.mean(axis=0)
        amp = float(np.sqrt(2.0 * np.mean(swing ** 2)))
        spec = np.fft.rfft(swing * np.hanning(F)[:, None], axis=0)
        power = (np.abs(spec) ** 2).sum(axis=1)
        k = 1 + int(np.argmax(power[1:])) if len(power) > 1 else 0
        phases = np.angle(spec[k])
        R = float(np.abs(np.mean(np.exp(1j * phases))))
        spread = float(np.sqrt(max(-2.0 * np.log(max(R, 1e-12)), 0.0))) + 0.0      # no -0.0
        out.append({"level": lv, "elements": int(len(sel)), "amplitude_deg": float(np.degrees(amp)),
                    "frequency_hz": float(k * fps / F), "phase_spread_rad": spread})
    return out


def pivot_elements(tree: Tree3D, rig: Rig) -> PivotPainter:
    """The PP2 data of ``rig`` (module docstring)."""
    elem, parent, level = branch_elements(rig)
    E = len(parent)
    if E > MAX_ELEMENTS:
        raise ValueError(f"{E} Pivot Painter elements; PP2's shader takes at most {MAX_ELEMENTS}: cut the bones (--bones)")
    base = element_bases(rig, elem, E)
    # the pivot is the element's first bone's head; its tip the farthest tail of its branch bones
    head = rig.head.astype(np.float64)
    tail = rig.tail.astype(np.float64)
    pivot = head[base]
    nb = rig.n_branch
    dist = np.linalg.norm(tail[:nb] - pivot[elem[:nb]], axis=1)
    tip = tail[base].copy()
    for b in np.argsort(dist):                                    # ascending: the last write wins
        tip[elem[b]] = tail[b]
    axis = tip - pivot
    length = np.linalg.norm(axis, axis=1)
    axis = axis / np.maximum(length, 1e-9)[:, None]
    pivot_u = pivot @ TO_UNREAL.T
    axis_u = axis @ np.diag([1.0, -1.0, 1.0])
    width = int(np.ceil(np.sqrt(E)))
    height = int(np.ceil(E / width))
    doc = {
        "format": "tree_from_video.pivot_painter", "version": 1, "elements": int(E), "width": width,
        "height": height, "levels": int(level.max()) + 1 if E else 0, "files": list(FILES[:2]),
        "layout": ("element i at column i mod width, row i div width from the top; pivot_pos_index.exr RGB "
                   "pivot (cm, Unreal axes), A parent index as Int-as-float (half bits = index + 1024, a root "
                   "itself); xaxis_extent.png RGB X axis packed (v+1)/2, A extent clamp(cm/8,1,256)/256; "
                   "vertex element in UV channel 1 at the pixel centre"),
        "units": "cm", "axes": "Unreal: +X forward, +Y right, +Z up (Blender (x, y, z) m -> (x, -y, z) * 100)",
        "import": ("EXR: HDR compression, sRGB off, no mipmaps, nearest filter; PNG: VectorDisplacementMap, "
                   "sRGB off, no mipmaps, nearest filter; mesh: combine meshes, full-precision UVs"),
        "wind": wind_levels(rig, elem, level, float(tree.fps)),
    }
    return PivotPainter(elem, parent, level, pivot_u, axis_u, length * 100.0, width, height, doc)


def textures(pp: PivotPainter) -> tuple[np.ndarray, np.ndarray]:
    """``(pos_index (H, W, 4) float16, xaxis_extent (H, W, 4) uint8 RGBA)``, row 0 the top."""
    E, W, H = len(pp.parent), pp.width, pp.height
    pos = np.zeros((H * W, 4), np.float16)
    pos[:E, :3] = pp.pivot
    pos[:E, 3] = int_as_float(pp.parent)
    pos[E:, 3] = int_as_float(np.zeros(H * W - E, np.int64))
    xe = np.zeros((H * W, 4), np.uint8)
    xe[:E, :3] = np.round((pp.xaxis + 1.0) / 2.0 * 255.0).astype(np.uint8)
    xe[:E, 3] = np.round(np.clip(pp.extent / 8.0, 1.0, 256.0) / 256.0 * 255.0).astype(np.uint8)
    return pos.reshape(H, W, 4), xe.reshape(H, W, 4)


def pivot_files(pp: PivotPainter) -> dict[str, bytes]:
    """The file contents by name: the two textures and ``pivot_painter.json``."""
    import cv2
    pos, xe = textures(pp)
    ok, png = cv2.imencode(".png", xe[..., [2, 1, 0, 3]])             # OpenCV writes BGRA
    if not ok:
        raise RuntimeError("OpenCV could not encode xaxis_extent.png")
    return {FILES[0]: exr_bytes(pos), FILES[1]: png.tobytes(), FILES[2]: json_bytes(pp.doc)}


def write_pivot_painter(folder: str | os.PathLike, pp: PivotPainter) -> list[str]:
    """The two textures and ``pivot_painter.json`` in ``folder``, atomically; their paths."""
    return write_files(folder, pivot_files(pp))
