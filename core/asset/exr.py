"""A writer of OpenEXR images in half float, what Pivot Painter 2's position texture and the bone
animation texture need: single part, scanlines, no compression, channels R, G, B, A (issue 33).

Written from the OpenEXR file layout ("The OpenEXR File Layout", openexr.com): the magic number
20000630 and version 2 (flags 0: single-part scanline), a header of attributes ``name\\0 type\\0
size(int32) value`` closed by a null byte (``channels`` chlist, ``compression`` 0 = none,
``dataWindow``/``displayWindow`` box2i, ``lineOrder`` 0 = increasing y, ``pixelAspectRatio``,
``screenWindowCenter``, ``screenWindowWidth``), a line offset table (one uint64 per scanline), then
per scanline ``y(int32) size(int32)`` and each channel's row in the channels' alphabetical order.
Row 0 of the array is the image's top (y = 0 of the data window). Little-endian throughout.
"""
from __future__ import annotations

import os
import struct

import numpy as np

from ..fileio import atomic_write_bytes

MAGIC = 20000630
HALF = 1


def _attr(name: str, kind: str, value: bytes) -> bytes:
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def exr_bytes(rgba: np.ndarray) -> bytes:
    """The EXR file of ``rgba (H, W, 4)`` (any float type; stored as half, channels R, G, B, A)."""
    img = np.asarray(rgba)
    if img.ndim != 3 or img.shape[2] != 4 or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"an EXR image is (H, W, 4), got {img.shape}")
    H, W = img.shape[:2]
    names = ("A", "B", "G", "R")                               # alphabetical, as the layout requires
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", HALF, 0, 1, 1) for n in names) + b"\0"
    box = struct.pack("<iiii", 0, 0, W - 1, H - 1)
    header = (struct.pack("<ii", MAGIC, 2)
              + _attr("channels", "chlist", chlist)
              + _attr("compression", "compression", b"\0")
              + _attr("dataWindow", "box2i", box)
              + _attr("displayWindow", "box2i", box)
              + _attr("lineOrder", "lineOrder", b"\0")
              + _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + _attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
              + _attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
              + b"\0")
    half = img.astype("<f2")
    # per scanline: the A row, then B, G, R (each W halfs)
    rows = np.stack([half[..., 3], half[..., 2], half[..., 1], half[..., 0]], axis=1)    # (H, 4, W)
    line_bytes = 4 * W * 2
    block = np.empty((H, 8 + line_bytes), np.uint8)
    block[:, :4] = np.arange(H, dtype="<i4").view(np.uint8).reshape(H, 4)
    block[:, 4:8] = np.full(H, line_bytes, "<i4").view(np.uint8).reshape(H, 4)
    block[:, 8:] = rows.reshape(H, -1).view(np.uint8)
    first = len(header) + 8 * H
    offsets = (first + np.arange(H, dtype=np.int64) * (8 + line_bytes)).astype("<u8")
    return header + offsets.tobytes() + block.tobytes()


def write_exr(path: str | os.PathLike, rgba: np.ndarray) -> None:
    """``rgba (H, W, 4)`` to ``path`` as a half-float EXR, atomically (row 0 at the top)."""
    atomic_write_bytes(path, exr_bytes(rgba))
