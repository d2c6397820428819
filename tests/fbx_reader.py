"""A minimal reader of binary FBX, written from the format's public description (Blender's
developer blog "FBX binary file format specification", 2013, which ``io_scene_fbx`` follows): a
23-byte magic, a uint32 version, then nested node records ``(end offset, property count, property
bytes, name length u8, name, properties, children…)`` (offsets uint64 from version 7500 on, uint32
before), a record of zeros closing each child list. Properties: ``Y`` i16, ``C`` bool, ``I`` i32,
``F`` f32, ``D`` f64, ``L`` i64, ``S``/``R`` length-prefixed bytes, ``f d l i b`` arrays (length,
encoding, compressed length; encoding 1 = zlib). Used to check what the exporter wrote (LOD group
nodes, object names) without Blender's own importer."""
import struct
import zlib

MAGIC = b"Kaydara FBX Binary  \x00\x1a\x00"
_SCALAR = {b"Y": "<h", b"C": "<?", b"I": "<i", b"F": "<f", b"D": "<d", b"L": "<q"}
_ARRAY = {b"f": "f", b"d": "d", b"l": "q", b"i": "i", b"b": "?"}


def _props(data, off, n):
    out = []
    for _ in range(n):
        t = data[off:off + 1]
        off += 1
        if t in _SCALAR:
            fmt = _SCALAR[t]
            out.append(struct.unpack_from(fmt, data, off)[0])
            off += struct.calcsize(fmt)
        elif t in (b"S", b"R"):
            (length,) = struct.unpack_from("<I", data, off)
            out.append(bytes(data[off + 4:off + 4 + length]))
            off += 4 + length
        elif t in _ARRAY:
            count, enc, clen = struct.unpack_from("<III", data, off)
            raw = bytes(data[off + 12:off + 12 + clen])
            off += 12 + clen
            raw = zlib.decompress(raw) if enc == 1 else raw
            out.append(struct.unpack(f"<{count}{_ARRAY[t]}", raw))
        else:
            raise ValueError(f"unknown FBX property type {t!r} at {off - 1}")
    return out, off


def _node(data, off, wide):
    head = "<QQQB" if wide else "<IIIB"
    end, nprops, _plen, nlen = struct.unpack_from(head, data, off)
    off += struct.calcsize(head)
    if end == 0:
        return None, off
    name = bytes(data[off:off + nlen]).decode()
    props, off = _props(data, off + nlen, nprops)
    children = []
    while off < end:
        child, off = _node(data, off, wide)
        if child is None:
            break
        children.append(child)
    return {"name": name, "props": props, "children": children}, end


def read_fbx(path) -> list[dict]:
    """The top-level nodes of a binary FBX file: ``{"name", "props", "children"}`` each."""
    data = open(path, "rb").read()
    assert data[:23] == MAGIC, "not a binary FBX"
    (version,) = struct.unpack_from("<I", data, 23)
    wide = version >= 7500
    nodes, off = [], 27
    while off < len(data):
        node, off = _node(data, off, wide)
        if node is None:
            break
        nodes.append(node)
    return nodes


def child(node: dict, name: str) -> list[dict]:
    return [c for c in node["children"] if c["name"] == name]


def top(nodes: list[dict], name: str) -> dict:
    return next(n for n in nodes if n["name"] == name)


def object_name(prop: bytes) -> str:
    """``b"Name\\x00\\x01Class"`` → ``"Name"``."""
    return prop.split(b"\x00\x01")[0].decode()
