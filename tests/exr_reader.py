"""A minimal OpenEXR reader written from "The OpenEXR File Layout" (openexr.com): magic 20000630,
version field (flags must be 0 here: single-part scanline), the header's attributes (``name\\0
type\\0 size value``, a null byte closes it), the line offset table (uint64 per scanline block),
then per block ``y(int32) size(int32)`` and, uncompressed, each channel's row in the order of the
``channels`` list (sorted by name), half = 2 bytes. Only what the product writes: no compression,
half channels, one line per block."""
import struct

import numpy as np


def read_exr(path) -> tuple[dict, np.ndarray]:
    """``(header {name: (type, raw bytes)}, pixels (H, W, C) float32)`` with channels in the
    file's (alphabetical) order; ``header["_channels"]`` their names."""
    data = open(path, "rb").read()
    magic, version = struct.unpack_from("<ii", data, 0)
    assert magic == 20000630 and version & 0xFF == 2 and version >> 8 == 0, (magic, version)
    off, header = 8, {}
    while data[off] != 0:
        end = data.index(b"\0", off)
        name = data[off:end].decode()
        tend = data.index(b"\0", end + 1)
        kind = data[end + 1:tend].decode()
        (size,) = struct.unpack_from("<i", data, tend + 1)
        header[name] = (kind, data[tend + 5:tend + 5 + size])
        off = tend + 5 + size
    off += 1
    assert header["compression"][1] == b"\0", "compressed EXR"
    chl, channels, types = header["channels"][1], [], []
    p = 0
    while chl[p] != 0:
        end = chl.index(b"\0", p)
        channels.append(chl[p:end].decode())
        ptype, _linear, xs, ys = struct.unpack_from("<iB3xii", chl, end + 1)
        assert (xs, ys) == (1, 1)
        types.append(ptype)
        p = end + 1 + 16
    assert all(t == 1 for t in types), "only half channels"
    x0, y0, x1, y1 = struct.unpack("<iiii", header["dataWindow"][1])
    W, H = x1 - x0 + 1, y1 - y0 + 1
    offsets = np.frombuffer(data, "<u8", H, off)
    out = np.empty((H, W, len(channels)), np.float32)
    for o in offsets:
        y, size = struct.unpack_from("<ii", data, int(o))
        assert size == 2 * W * len(channels)
        row = np.frombuffer(data, "<f2", W * len(channels), int(o) + 8).reshape(len(channels), W)
        out[y - y0] = row.T
    header["_channels"] = channels
    return header, out


def rgba(path) -> np.ndarray:
    """``(H, W, 4)`` R, G, B, A of an EXR holding those four channels."""
    header, px = read_exr(path)
    ch = header["_channels"]
    return np.stack([px[..., ch.index(c)] for c in "RGBA"], axis=-1)
