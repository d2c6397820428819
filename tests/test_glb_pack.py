"""Packing a game GLB (core/asset/glb_pack.py, issue 33 item 8), checked against the glTF 2.0 spec
with a reader of our own (tests/test_engine_files_scene.read_accessor) and the Khronos validator:
weights become normalized bytes that still sum to one per vertex and stay within 1/255 of the
exporter's; colours within 1/255; UV sets in [0, 1] normalized shorts within 1/65535 (the bark's
tiling UVs stay float); positions, normals, indices, joints, morph targets and every rotation and
translation key come through unchanged; only the scale channels that are all 1 go; the file shrinks."""
import bpy
import numpy as np
import pytest
from browser import validate_glb
from test_engine_files_scene import read_accessor

from tree_from_video import api
from tree_from_video.core.asset.glb_pack import pack_glb, read_glb
from tree_from_video.operators.scene import build, export, trees

from trees import empty_scene  # noqa: F401  (autouse fixture)

pytestmark = [pytest.mark.browser]


def _value(doc, binary, i) -> np.ndarray:
    """An accessor's values as floats, normalized integers scaled (glTF 2.0 §3.11)."""
    a = doc["accessors"][i]
    if "bufferView" in a:
        v = read_accessor(doc, binary, i).astype(np.float64)
    else:                                                    # zeros, then the sparse values (§3.6.2.3)
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
        v = np.zeros((a["count"], width))
    sp = a.get("sparse")
    if sp:
        iv, vv = doc["bufferViews"][sp["indices"]["bufferView"]], doc["bufferViews"][sp["values"]["bufferView"]]
        idt = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32}[sp["indices"]["componentType"]]
        idx = np.frombuffer(binary, idt, sp["count"], iv.get("byteOffset", 0) + sp["indices"].get("byteOffset", 0))
        vals = np.frombuffer(binary, np.float32, sp["count"] * v.shape[1],
                             vv.get("byteOffset", 0) + sp["values"].get("byteOffset", 0))
        v[idx.astype(np.int64)] = vals.reshape(-1, v.shape[1])
    if a.get("normalized"):
        v /= {5121: 255.0, 5123: 65535.0}[a["componentType"]]
    return v


def test_packing_keeps_the_asset(tmp_path):
    tree, = api.generate("broad", node_budget=100, n_frames=36, seed=95)
    built = build.build_tree(bpy.context, tree, "Pack", bone_budget=24, lods=2, pivots=True)
    path = export.export_gltf(tmp_path / "plain.glb", trees.tree_objects(built["collection"]))
    data = open(path, "rb").read()
    packed, rep = pack_glb(data)
    (tmp_path / "packed.glb").write_bytes(packed)
    assert rep.after < 0.85 * rep.before and rep.weights and rep.colours and rep.texcoords
    a_doc, a_bin = read_glb(data)
    b_doc, b_bin = read_glb(packed)
    assert [m["name"] for m in a_doc["meshes"]] == [m["name"] for m in b_doc["meshes"]]
    floats_kept = 0
    for ma, mb in zip(a_doc["meshes"], b_doc["meshes"]):
        for pa, pb in zip(ma["primitives"], mb["primitives"]):
            assert set(pa["attributes"]) == set(pb["attributes"])
            for name, ia in pa["attributes"].items():
                va, vb = _value(a_doc, a_bin, ia), _value(b_doc, b_bin, pb["attributes"][name])
                if name.startswith("WEIGHTS"):
                    assert np.abs(va - vb).max() <= 1 / 255 + 1e-9
                    assert np.allclose(vb.sum(axis=1), 1.0, atol=1e-9)
                elif name.startswith("COLOR"):
                    assert np.abs(va - vb).max() <= 0.5 / 255 + 1e-6
                elif name.startswith("TEXCOORD"):
                    assert np.abs(va - vb).max() <= 0.5 / 65535 + 1e-7
                    floats_kept += b_doc["accessors"][pb["attributes"][name]]["componentType"] == 5126
                else:
                    assert np.array_equal(va, vb), name
            assert np.array_equal(_value(a_doc, a_bin, pa["indices"]), _value(b_doc, b_bin, pb["indices"]))
            for ta, tb in zip(pa.get("targets", []), pb.get("targets", [])):
                for k in ta:
                    assert np.array_equal(_value(a_doc, a_bin, ta[k]), _value(b_doc, b_bin, tb[k]))
    assert floats_kept >= 1                                  # the bark's tiling UVs
    # animation: every channel but the constant scales, the same keys
    (aa,), (ab,) = a_doc["animations"], b_doc["animations"]
    kept = [(c["target"]["node"], c["target"]["path"]) for c in ab["channels"]]
    for c in aa["channels"]:
        key = (c["target"]["node"], c["target"]["path"])
        s = aa["samplers"][c["sampler"]]
        out = _value(a_doc, a_bin, s["output"])
        if c["target"]["path"] == "scale" and np.allclose(out, 1.0, atol=1e-6):
            assert key not in kept
            continue
        cb = ab["channels"][kept.index(key)]
        sb = ab["samplers"][cb["sampler"]]
        assert np.array_equal(_value(b_doc, b_bin, sb["output"]), out)
        assert np.array_equal(_value(b_doc, b_bin, sb["input"]), _value(a_doc, a_bin, s["input"]))
    report, = validate_glb(tmp_path / "packed.glb")
    assert report["errors"] == 0, report["messages"]
