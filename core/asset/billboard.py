"""The billboard of a tree (issue 36 part 2, ``--billboard PX``): its front at rest, orthographic,
framed on the tree, ``PX`` pixels on the longer side: ``billboard.png`` (RGBA 8-bit sRGB, alpha the
rendered coverage), ``billboard_normal.png`` (RGB the surface normal in glTF axes as ``(n + 1) / 2``,
A the coverage; the impostor's encoding, :mod:`.impostor`) and ``billboard.json`` (its scale and
where the tree's origin lands, so an engine stands the card where the tree stands). Such a picture
is also an exemplar for :mod:`..generate.variations`.

The view looks along Blender's +Y (the tree's front, glTF +Z, towards the viewer), image right =
+X, image up = +Z. The frame is the rest points' box in X and Z grown by :data:`MARGIN` of its
longer side each way; pixel ``(x, y)`` (from the top left, centres at +½) is the point
``centre + (x + ½ − W/2) · m right − (y + ½ − H/2) · m up`` with ``m`` metres per pixel. Pure numpy:
the renders are Blender's (:mod:`operators.scene.impostor`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .axes import TO_GLTF

FILES = ("billboard.png", "billboard_normal.png", "billboard.json")
#: the billboard's pixels on its longer side, the range ``--billboard`` takes
BILLBOARD_PX = (16, 8192)
#: the panel's Billboard size (pixels on the longer side)
DEFAULT_PX = 512
#: the frame's margin around the tree, share of its longer side, each way
MARGIN = 0.02


@dataclass
class BillboardView:
    """``centre (3,)`` metres Blender axes; ``px (W, H)``; ``metres_per_px``; ``depth`` how far
    back the camera stands (metres)."""

    centre: np.ndarray
    px: tuple[int, int]
    metres_per_px: float
    depth: float
    forward: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    right: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    @property
    def ortho_scale(self) -> float:
        """Metres across the longer side (Blender's orthographic scale)."""
        return self.metres_per_px * max(self.px)

    def project(self, points: np.ndarray) -> np.ndarray:
        """``(P, 2)`` pixel coordinates (x right, y down, pixel centres at +½) of ``points (P, 3)``
        (metres, Blender axes)."""
        d = np.asarray(points, np.float64) - self.centre
        w, h = self.px
        x = d @ self.right / self.metres_per_px + 0.5 * w
        y = 0.5 * h - d @ self.up / self.metres_per_px
        return np.stack([x, y], axis=-1)


def billboard_view(points: np.ndarray, px: int) -> BillboardView:
    """The front view framing rest ``points (P, 3)`` (metres, Blender axes) with ``px`` pixels on
    its longer side (module docstring)."""
    p = np.asarray(points, np.float64)
    lo, hi = p.min(0), p.max(0)
    size = np.array([hi[0] - lo[0], hi[2] - lo[2]])
    side = float(max(size.max(), 1e-6)) * (1.0 + 2.0 * MARGIN)
    m = side / int(px)
    w = max(int(np.ceil((size[0] + 2 * MARGIN * size.max()) / m)), 1)
    h = max(int(np.ceil((size[1] + 2 * MARGIN * size.max()) / m)), 1)
    centre = 0.5 * (lo + hi)
    depth = float(np.linalg.norm(hi - lo)) + 1.0
    return BillboardView(centre, (min(w, int(px)), min(h, int(px))), m, depth)


def billboard_doc(view: BillboardView, tree_name: str, base: np.ndarray | None = None) -> dict:
    """``billboard.json``: the files, the size, the scale and where the tree's origin lands (its
    base ``base (3,)`` in the view's metres; None: the world origin)."""
    origin = view.project(np.zeros((1, 3)) if base is None else np.asarray(base, np.float64).reshape(1, 3))[0]
    return {
        "format": "tree_from_video.billboard", "version": 1, "tree": tree_name,
        "files": {"albedo": FILES[0], "normal": FILES[1]},
        "size_px": list(view.px), "metres_per_px": round(view.metres_per_px, 7),
        "width_m": round(view.px[0] * view.metres_per_px, 5), "height_m": round(view.px[1] * view.metres_per_px, 5),
        "origin_px": [round(float(origin[0]), 3), round(float(origin[1]), 3)],
        "view": "front, orthographic: looking along glTF -Z (Blender +Y); image right = +X, image up = +Y (glTF)",
        "view_direction_gltf": np.round(TO_GLTF @ -view.forward, 5).tolist(),
        "albedo_encoding": "RGBA 8-bit sRGB, alpha the coverage (alpha-test at 0.5)",
        "normal_encoding": "RGB 8-bit linear, (n + 1) / 2 of the surface normal in glTF axes; A the coverage",
    }


def billboard_files(view: BillboardView, albedo: np.ndarray, normal: np.ndarray, tree_name: str,
                    base: np.ndarray | None = None) -> dict[str, bytes]:
    """``{name: bytes}`` of :data:`FILES`: the renders ``(H, W, 4)`` uint8 RGBA as PNGs and the doc
    (the tree's base at ``base (3,)`` metres, :func:`billboard_doc`)."""
    import cv2

    from ..fileio import json_bytes
    out = {}
    for name, img in zip(FILES[:2], (albedo, normal)):
        ok, png = cv2.imencode(".png", np.ascontiguousarray(img[..., [2, 1, 0, 3]]))
        if not ok:
            raise RuntimeError(f"OpenCV could not encode {name}")
        out[name] = png.tobytes()
    out[FILES[2]] = json_bytes(billboard_doc(view, tree_name, base))
    return out
