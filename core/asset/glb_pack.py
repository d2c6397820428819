"""Packing a game GLB (issue 33 item 8): the same asset in fewer bytes, with what the glTF 2.0 core
spec already allows every loader to read (no extension):

* ``WEIGHTS_n`` float → unsigned byte, normalized (§3.7.3.3: "unsigned byte normalized"), each
  vertex's four weights rounded to 1/255 and their sum kept at exactly 255 (the largest takes the
  rounding);
* ``COLOR_n`` float → unsigned byte, normalized (allowed the same way);
* ``TEXCOORD_n`` float → unsigned short, normalized, when every value lies in [0, 1] (the leaves'
  UVs, Pivot Painter's element UVs; the bark's tiling UVs stay float);
* animation channels of ``scale`` whose every value is 1 (a rig that never scales) are left out
  (glTF: an unanimated property keeps the node's value, 1);
* the binary chunk rebuilt from the buffer views still used, each 4-byte aligned
  (§3.6.2.4: accessor offsets a multiple of the component size; vertex strides a multiple of 4).

The Blender exporter writes floats for all of these; at 64 bones, three LODs and leaves they were
2.5 MB of an 8.2 MB GLB. Pure Python and numpy (the GLB container: magic ``glTF``, version 2,
a JSON chunk padded with spaces, a BIN chunk padded with zeros).
"""
from __future__ import annotations

import json
import os
import struct
from dataclasses import dataclass

import numpy as np

from ..fileio import atomic_write_bytes

FLOAT, UBYTE, USHORT = 5126, 5121, 5123
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
DTYPE = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}


@dataclass
class PackReport:
    """Bytes before and after; what was converted."""

    before: int
    after: int
    weights: int = 0
    colours: int = 0
    texcoords: int = 0
    scale_channels: int = 0

    def line(self) -> str:
        return (f"{self.before / 1e6:.1f} -> {self.after / 1e6:.1f} MB (weights {self.weights}, colours "
                f"{self.colours}, UV sets {self.texcoords} packed; {self.scale_channels} constant scale channels out)")


def read_glb(data: bytes) -> tuple[dict, bytes]:
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2 or length != len(data):
        raise ValueError("not a binary glTF 2.0 file")
    off, chunks = 12, []
    while off < len(data):
        size, kind = struct.unpack_from("<II", data, off)
        chunks.append((kind, data[off + 8:off + 8 + size]))
        off += 8 + size
    doc = json.loads(chunks[0][1])
    binary = chunks[1][1] if len(chunks) > 1 else b""
    return doc, binary


def write_glb(doc: dict, binary: bytes) -> bytes:
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    binary = binary + b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<II", len(js), 0x4E4F534A) + js
            + struct.pack("<II", len(binary), 0x004E4942) + binary)


def accessor_array(doc: dict, binary: bytes, index: int) -> np.ndarray:
    """``(count, width)`` values of accessor ``index`` as stored (normalized integers not scaled)."""
    a = doc["accessors"][index]
    dt = np.dtype(DTYPE[a["componentType"]])
    width = WIDTH[a["type"]]
    view = doc["bufferViews"][a["bufferView"]]
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    stride = view.get("byteStride", dt.itemsize * width)
    count = a["count"]
    raw = np.frombuffer(binary, np.uint8, stride * (count - 1) + dt.itemsize * width if count else 0, start)
    return np.lib.stride_tricks.as_strided(raw.view(dt), (count, width), (stride, dt.itemsize)).copy()


def _pack_weights(w: np.ndarray) -> np.ndarray:
    """Float weights ``(V, 4)`` → uint8 summing to exactly 255 per vertex."""
    w = np.clip(np.nan_to_num(w), 0.0, None)
    s = w.sum(axis=1, keepdims=True)
    w = np.where(s > 0, w / np.where(s > 0, s, 1.0), np.eye(w.shape[1])[0])
    q = np.floor(w * 255.0 + 0.5).astype(np.int64)
    big = np.argmax(w, axis=1)
    q[np.arange(len(q)), big] += 255 - q.sum(axis=1)
    return np.clip(q, 0, 255).astype(np.uint8)


def pack_glb(data: bytes) -> tuple[bytes, PackReport]:
    """The packed GLB of ``data`` (module docstring) and what changed."""
    doc, binary = read_glb(data)
    acc = doc.get("accessors", [])
    new_arrays: dict[int, tuple[np.ndarray, int, bool]] = {}     # accessor → (values, componentType, normalized)
    rep = PackReport(len(data), 0)
    seen: set[int] = set()
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            for name, i in prim.get("attributes", {}).items():
                if i in seen or acc[i].get("componentType") != FLOAT or acc[i].get("sparse"):
                    continue
                if name.startswith("WEIGHTS_") and acc[i]["type"] == "VEC4":
                    new_arrays[i] = (_pack_weights(accessor_array(doc, binary, i)), UBYTE, True)
                    rep.weights += 1
                elif name.startswith("COLOR_"):
                    v = np.clip(accessor_array(doc, binary, i), 0.0, 1.0)
                    new_arrays[i] = (np.floor(v * 255.0 + 0.5).astype(np.uint8), UBYTE, True)
                    rep.colours += 1
                elif name.startswith("TEXCOORD_"):
                    v = accessor_array(doc, binary, i)
                    if v.size and v.min() >= 0.0 and v.max() <= 1.0:
                        new_arrays[i] = (np.floor(v * 65535.0 + 0.5).astype(np.uint16), USHORT, True)
                        rep.texcoords += 1
                seen.add(i)
    # constant scale channels
    for anim in doc.get("animations", []):
        keep = []
        for ch in anim["channels"]:
            if ch["target"].get("path") == "scale":
                vals = accessor_array(doc, binary, anim["samplers"][ch["sampler"]]["output"])
                if vals.size and np.allclose(vals, 1.0, atol=1e-6):
                    rep.scale_channels += 1
                    continue
            keep.append(ch)
        used = sorted({ch["sampler"] for ch in keep})
        remap = {s: k for k, s in enumerate(used)}
        anim["samplers"] = [anim["samplers"][s] for s in used]
        for ch in keep:
            ch["sampler"] = remap[ch["sampler"]]
        anim["channels"] = keep
    # the accessors still used, and the views they (or images) use, rebuilt into a fresh buffer
    used_acc = _used_accessors(doc)
    acc_map = {old: new for new, old in enumerate(sorted(used_acc))}
    views_out: list[dict] = []
    chunks: list[bytes] = []
    offset = 0

    def add_view(payload: bytes, extra: dict) -> int:
        nonlocal offset
        pad = -offset % 4
        if pad:
            chunks.append(b"\0" * pad)
            offset += pad
        view = {"buffer": 0, "byteOffset": offset, "byteLength": len(payload)}
        view.update(extra)
        views_out.append(view)
        chunks.append(payload)
        offset += len(payload)
        return len(views_out) - 1

    new_acc = []
    for old in sorted(used_acc):
        a = dict(acc[old])
        if "bufferView" in a:
            if old in new_arrays:
                values, ctype, norm = new_arrays[old]
                a["componentType"], a["normalized"] = ctype, norm
                a.pop("byteOffset", None)
                itemsize = np.dtype(values.dtype).itemsize * values.shape[1]
                stride = {"byteStride": itemsize + (-itemsize % 4)} if itemsize % 4 else {}
                if stride:                               # pad each element to a 4-byte stride
                    padded = np.zeros((len(values), stride["byteStride"]), np.uint8)
                    padded[:, :itemsize] = values.view(np.uint8).reshape(len(values), itemsize)
                    payload = padded.tobytes()
                else:
                    payload = np.ascontiguousarray(values).tobytes()
                target = doc["bufferViews"][a["bufferView"]].get("target")
                a["bufferView"] = add_view(payload, dict(stride, **({"target": target} if target else {})))
                for key in ("min", "max"):
                    if key in a:
                        a[key] = (values.min(0) if key == "min" else values.max(0)).astype(int).tolist()
            else:
                a["bufferView"] = _copy_view(doc, binary, a, add_view)
                a.pop("byteOffset", None)
        if "sparse" in a:                            # its indices and values, each a view of its own
            sp = json.loads(json.dumps(a["sparse"]))
            for part in ("indices", "values"):
                v = doc["bufferViews"][sp[part]["bufferView"]]
                start = v.get("byteOffset", 0) + sp[part].get("byteOffset", 0)
                end = v.get("byteOffset", 0) + v["byteLength"]
                sp[part]["bufferView"] = add_view(binary[start:end], {})
                sp[part].pop("byteOffset", None)
            a["sparse"] = sp
        new_acc.append(a)
    for img in doc.get("images", []):
        if "bufferView" in img:
            v = doc["bufferViews"][img["bufferView"]]
            start = v.get("byteOffset", 0)
            img["bufferView"] = add_view(binary[start:start + v["byteLength"]], {})
    doc["accessors"] = new_acc
    _remap_accessors(doc, acc_map)
    doc["bufferViews"] = views_out
    payload = b"".join(chunks)
    doc["buffers"] = [{"byteLength": len(payload) + (-len(payload) % 4)}]
    packed = write_glb(doc, payload)
    rep.after = len(packed)
    return packed, rep


def _copy_view(doc: dict, binary: bytes, a: dict, add_view) -> int:
    """The bytes accessor ``a`` reads, copied into a view of their own (its stride kept)."""
    view = doc["bufferViews"][a["bufferView"]]
    dt = np.dtype(DTYPE[a["componentType"]])
    elem = dt.itemsize * WIDTH[a["type"]]
    stride = view.get("byteStride", elem)
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    length = stride * (a["count"] - 1) + elem if a["count"] else 0
    extra = {k: view[k] for k in ("byteStride", "target") if k in view}
    return add_view(binary[start:start + length], extra)


def _used_accessors(doc: dict) -> set[int]:
    used: set[int] = set()
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            used.update(prim.get("attributes", {}).values())
            if "indices" in prim:
                used.add(prim["indices"])
            for t in prim.get("targets", []):
                used.update(t.values())
    for skin in doc.get("skins", []):
        if "inverseBindMatrices" in skin:
            used.add(skin["inverseBindMatrices"])
    for anim in doc.get("animations", []):
        for s in anim["samplers"]:
            used.update((s["input"], s["output"]))
    return used


def _remap_accessors(doc: dict, m: dict[int, int]) -> None:
    for mesh in doc.get("meshes", []):
        for prim in mesh.get("primitives", []):
            prim["attributes"] = {k: m[v] for k, v in prim.get("attributes", {}).items()}
            if "indices" in prim:
                prim["indices"] = m[prim["indices"]]
            if "targets" in prim:
                prim["targets"] = [{k: m[v] for k, v in t.items()} for t in prim["targets"]]
    for skin in doc.get("skins", []):
        if "inverseBindMatrices" in skin:
            skin["inverseBindMatrices"] = m[skin["inverseBindMatrices"]]
    for anim in doc.get("animations", []):
        for s in anim["samplers"]:
            s["input"], s["output"] = m[s["input"]], m[s["output"]]


def pack_glb_file(path: str | os.PathLike) -> PackReport:
    """Pack the GLB at ``path`` in place, atomically."""
    data = open(path, "rb").read()
    out, rep = pack_glb(data)
    atomic_write_bytes(path, out)
    return rep
