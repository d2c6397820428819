"""The bark as images (core/detail/bark_texture.py, issue 32 item 3): seamless on the branch mesh's
UV square, its mean the bark's colour, relief as strong as the kind asks; and the exports carry them
(GLB: base colour and normal textures; FBX: an image on the re-imported bark), the procedural
material untouched afterwards."""
import json
import struct

import numpy as np
import pytest

from tree_from_video.core.detail.albedo import srgb_to_linear
from tree_from_video.core.detail.bark_texture import bark_ramp, bark_textures, periodic_noise


def _normals(tex):
    return tex.normal.astype(float) / 255.0 * 2.0 - 1.0


def test_noise_is_periodic_on_both_axes():
    """Across the wrap (last column → first, last row → first) the noise steps like anywhere inside:
    no seam where u goes round the tube or v repeats along it."""
    n = periodic_noise(128, (6.0, 4.0), np.random.default_rng(1))
    inside_u = np.abs(np.diff(n, axis=1)).mean()
    inside_v = np.abs(np.diff(n, axis=0)).mean()
    assert np.abs(n[:, -1] - n[:, 0]).mean() < 1.5 * inside_u
    assert np.abs(n[-1] - n[0]).mean() < 1.5 * inside_v
    assert 0.45 < n.mean() < 0.55 and n.min() >= 0 and n.max() <= 1


@pytest.mark.parametrize("colour", [None, (0.45, 0.38, 0.3), (0.6, 0.6, 0.62)])
def test_the_albedo_averages_to_the_bark_colour(colour):
    """The mean linear albedo is the ramp's middle: the video's bark colour (dark 0.35 ×, light
    1.65 ×), or the default ramp's — within 4 % of each channel (clipping at the ends aside)."""
    tex = bark_textures(colour, "rough", 256)
    got = srgb_to_linear(tex.albedo.astype(float) / 255.0).reshape(-1, 3).mean(0)
    dark, light = (np.asarray(e[:3]) for e in bark_ramp(colour))
    want = 0.5 * (dark + light)
    np.testing.assert_allclose(got, want, rtol=0.04)
    if colour is not None:
        np.testing.assert_allclose(want, srgb_to_linear(np.asarray(colour)), rtol=1e-9)


def test_relief_follows_the_kind_and_furrows_run_along_the_branch():
    flat = {k: np.linalg.norm(_normals(bark_textures(None, k, 256))[..., :2], axis=-1).mean()
            for k in ("none", "smooth", "rough")}
    assert flat["rough"] > flat["none"] > flat["smooth"] > 0.01      # BARK_LOOK's strengths 0.6, 0.35, 0.2
    n = _normals(bark_textures(None, "rough", 256))
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=0.01)   # unit vectors
    assert (n[..., 2] > 0).all()                                               # out of the surface
    # furrows along v (the branch): the relief changes faster across u than along v
    assert np.abs(n[..., 0]).mean() > 1.3 * np.abs(n[..., 1]).mean()


def _glb(path):
    data = open(path, "rb").read()
    n = struct.unpack("<I", data[12:16])[0]
    doc = json.loads(data[20:20 + n])
    binary = data[20 + n + 8:]
    return doc, binary


@pytest.mark.blender
@pytest.mark.bpy53
def test_exports_carry_the_baked_bark_and_leave_the_material_as_it_was(tmp_path):
    import bpy

    from tree_from_video.operators.scene import build, export

    from trees import broad_tree, empty_scene  # noqa: F401
    bpy.ops.wm.read_factory_settings(use_empty=True)
    tree = broad_tree(12)
    tree.meta = {"bark_colour": {"colour": [0.45, 0.38, 0.3]}}
    res = build.build_tree(bpy.context, tree, "Oak", bark="rough")
    mat = res["material"]
    links_before = sorted((lk.from_node.name, lk.to_node.name) for lk in mat.node_tree.links)
    images_before = {im.name for im in bpy.data.images}
    glb = export.export_gltf(tmp_path / "oak.glb", [res["armature"], res["mesh"]])
    fbx = export.export_fbx(tmp_path / "oak.fbx", [res["armature"], res["mesh"]])
    assert sorted((lk.from_node.name, lk.to_node.name) for lk in mat.node_tree.links) == links_before
    assert {im.name for im in bpy.data.images} == images_before

    doc, binary = _glb(glb)
    bark = next(m for m in doc["materials"] if "Bark" in m["name"])
    assert "baseColorTexture" in bark["pbrMetallicRoughness"] and "normalTexture" in bark
    # the base colour image, decoded: its mean linear colour within 10 % of the bark's colour
    import cv2
    tex = doc["textures"][bark["pbrMetallicRoughness"]["baseColorTexture"]["index"]]
    view = doc["bufferViews"][doc["images"][tex["source"]]["bufferView"]]
    png = np.frombuffer(binary[view.get("byteOffset", 0):view.get("byteOffset", 0) + view["byteLength"]], np.uint8)
    rgb = cv2.cvtColor(cv2.imdecode(png, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    mean = srgb_to_linear(rgb.astype(float) / 255.0).reshape(-1, 3).mean(0)
    np.testing.assert_allclose(mean, srgb_to_linear(np.array([0.45, 0.38, 0.3])), rtol=0.10)

    # FBX: re-imported, the bark material's base colour is an image (it was white: no texture)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.fbx(filepath=str(fbx))
    imported = next(m for m in bpy.data.materials if "Bark" in m.name)
    bsdf = next(n for n in imported.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    src = bsdf.inputs["Base Color"].links[0].from_node
    assert src.type == "TEX_IMAGE" and src.image is not None and src.image.size[0] == 512
    px = srgb_to_linear(np.array(src.image.pixels[:]).reshape(-1, 4)[:, :3]).mean(0)   # stored sRGB
    np.testing.assert_allclose(px, srgb_to_linear(np.array([0.45, 0.38, 0.3])), rtol=0.10)
