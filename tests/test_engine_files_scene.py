"""The engine files of a game export in Blender (issue 33): the batch's outputs with a bone budget,
two LODs, Pivot Painter 2, the bone texture and collision capsules (in the FBX under their
``UCP_`` names, listed in collision.json, left out of the GLB). Every GLB primitive carries UV channel 1
(TEXCOORD_1) pointing at the PP2 element of its vertex's joint (read from the GLB's own joints and
the texture layout Epic describes); the FBX and the .blend files are not touched; Blender itself
loads both EXRs with the sizes and values our EXR reader reads (the format written from the
OpenEXR layout is one Blender's OpenImageIO takes)."""
import json

import bpy
import numpy as np
import pytest
from exr_reader import rgba
from fbx_reader import child, object_name, read_fbx, top
from test_exports import read_glb
from test_pivot_painter import element_at_uv

from tree_from_video import api
from tree_from_video.core.asset.game import GameSettings
from tree_from_video.operators.scene import outputs

from trees import empty_scene  # noqa: F401  (autouse fixture)

pytestmark = [pytest.mark.blender]

_TYPES = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def read_accessor(doc, binary, index) -> np.ndarray:
    """An accessor's ``(count, width)`` values (glTF 2.0 §3.6: buffer view, offsets, stride)."""
    a = doc["accessors"][index]
    dt = np.dtype(_TYPES[a["componentType"]])
    width = _WIDTH[a["type"]]
    view = doc["bufferViews"][a["bufferView"]]
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    stride = view.get("byteStride", dt.itemsize * width)
    raw = np.frombuffer(binary, np.uint8, stride * (a["count"] - 1) + dt.itemsize * width, start)
    return np.lib.stride_tricks.as_strided(raw.view(dt), (a["count"], width), (stride, dt.itemsize)).copy()


def read_values(doc, binary, index) -> np.ndarray:
    """An accessor's values as floats, normalized integers scaled to [0, 1] (glTF 2.0 §3.11)."""
    a = doc["accessors"][index]
    v = read_accessor(doc, binary, index).astype(np.float64)
    if a.get("normalized"):
        v /= float(np.iinfo(_TYPES[a["componentType"]]).max)
    return v


def test_game_export_files(tmp_path):
    tree, = api.generate("broad", node_budget=90, n_frames=30, seed=61)
    game = GameSettings(bones=24, lods=2, pivot_painter=True, bone_texture=True, collision=True)
    written = outputs.write_outputs(tree, str(tmp_path), {"gltf": True, "fbx": True}, fresh_scene=False,
                                    report=lambda m: None, game=game)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["tree.glb", "tree.fbx"] + game.files())
    # the capsules: in the FBX under Unreal's names, not in the GLB
    caps = [c["name"] for c in json.load(open(tmp_path / "collision.json"))["capsules"]]
    assert caps and all(c.startswith(f"UCP_{tree.name.replace(' ', '_')}_") for c in caps)
    models = {object_name(n["props"][1]) for n in child(top(read_fbx(written["fbx"]), "Objects"), "Model")}
    assert set(caps) <= models and {f"{tree.name}_LOD0", f"{tree.name}_LOD1"} <= models
    pp_doc = json.load(open(tmp_path / "pivot_painter.json"))
    W, H = pp_doc["width"], pp_doc["height"]
    doc, binary = read_glb(written["gltf"])
    skin_joints = [doc["nodes"][j]["name"] for j in doc["skins"][0]["joints"]]
    rig = bpy.data.objects[f"{tree.name} Rig"]
    # the PP2 element of each bone, from the built asset's own mapping
    from tree_from_video.core.asset import tree_asset
    pp = tree_asset(tree, bone_budget=24, pivots=True).pivots
    bone_names = [b.name for b in rig.data.bones]
    names = tree_asset(tree, bone_budget=24).rig.names
    assert sorted(bone_names) == sorted(names)
    elem_of_name = {n: int(pp.element_of_bone[k]) for k, n in enumerate(names)}
    checked = 0
    assert not any(m["name"].startswith("UCP_") for m in doc["meshes"])
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            attrs = prim["attributes"]
            assert "TEXCOORD_1" in attrs, f"{mesh['name']}: no UV channel 1"
            uv1 = read_values(doc, binary, attrs["TEXCOORD_1"])
            joints = read_accessor(doc, binary, attrs["JOINTS_0"])
            weights = read_values(doc, binary, attrs["WEIGHTS_0"])
            main = joints[np.arange(len(joints)), np.argmax(weights, axis=1)]
            uv_blender = np.stack([uv1[:, 0], 1.0 - uv1[:, 1]], axis=1)          # glTF's V runs down
            got = element_at_uv(uv_blender, W, H)
            want = np.array([elem_of_name[skin_joints[j]] for j in main])
            assert np.array_equal(got, want), mesh["name"]
            checked += len(got)
    assert checked > 1000
    # Blender reads both EXRs as we wrote them
    for name in ("pivot_pos_index.exr", "bone_anim.exr"):
        img = bpy.data.images.load(str(tmp_path / name))
        try:
            w, h = img.size
            ours = rgba(tmp_path / name)
            assert (h, w) == ours.shape[:2]
            px = np.empty(w * h * 4, np.float32)
            img.pixels.foreach_get(px)
            theirs = px.reshape(h, w, 4)[::-1]                     # Blender's rows run bottom-up
            assert np.allclose(theirs, ours, atol=1e-3 * max(1.0, float(np.abs(ours).max()))), name
        finally:
            bpy.data.images.remove(img)
