"""Bark from photos in the product (issue 36): ``batch.py VIDEO ... --bark-image PHOTO --gltf``
writes the tile's maps beside the tree and a GLB whose bark material carries them
(``baseColorTexture``, ``normalTexture``, read back from the file as the glTF 2.0 specification lays
them out: images in bufferViews); a bad bark photo is one line, exit 2, nothing written."""
import json
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest
from bark_photos import bark_pair, bark_photo
from job_report import check_report
from test_exports import read_glb

from tree_from_video.core.detail.bark_photo import moss_lichen, up_weight

from samples import ROOT, committed

pytestmark = [pytest.mark.bpy53]

BATCH = os.path.join(ROOT, "batch.py")
VIDEO = os.path.join(committed("broad"), "video.mp4")
OUTLINE = os.path.join(committed("broad"), "outline.json")
QUICK = ["--frames", "0:12", "--no-video", "--levels", "4", "--twigs", "0", "--no-leaves", "--quiet"]


def run(*args):
    p = subprocess.run([sys.executable, BATCH, *map(str, args)], capture_output=True, text=True, timeout=900)
    return p.returncode, p.stderr


def glb_image(doc, binary, index) -> np.ndarray:
    """Image ``index`` of a GLB, decoded (BGR) from its bufferView."""
    view = doc["bufferViews"][doc["images"][index]["bufferView"]]
    start = view.get("byteOffset", 0)
    return cv2.imdecode(np.frombuffer(binary[start:start + view["byteLength"]], np.uint8), cv2.IMREAD_COLOR)


def test_the_bark_photo_reaches_the_glb(tmp_path):
    photo, _, _ = bark_photo(7)
    path = tmp_path / "bark.jpg"
    cv2.imwrite(str(path), photo)
    out = tmp_path / "oak"
    code, err = run(VIDEO, "--outline", OUTLINE, "--out", out, *QUICK, "--gltf", "--usd", "--bark-image", path,
                    "--moss", "0", "--bark-scale", "40")
    assert code == 0, err
    for name in ("bark_albedo.png", "bark_normal.png", "bark_roughness.png", "bark_height.png", "bark.json"):
        assert (out / name).is_file(), name
    info = json.loads((out / "bark.json").read_text())
    assert info["tile_cm"] == 40.0 and info["moss_cover"]["tile"] == 0.0
    report = check_report(out)
    assert report["settings"]["bark_image"] == [str(path)] and "bark" in report["stages"]
    doc, binary = read_glb(out / "tree.glb")
    bark = next(m for m in doc["materials"] if "Bark" in m["name"])
    pbr = bark["pbrMetallicRoughness"]
    albedo = glb_image(doc, binary, doc["textures"][pbr["baseColorTexture"]["index"]]["source"])
    normal = glb_image(doc, binary, doc["textures"][bark["normalTexture"]["index"]]["source"])
    tile = cv2.imread(str(out / "bark_albedo.png"))
    print(f"\nGLB bark: albedo {albedo.shape}, mean {albedo.reshape(-1, 3).mean(0).round(1)} "
          f"(tile {tile.reshape(-1, 3).mean(0).round(1)}); normal mean {normal.reshape(-1, 3).mean(0).round(1)}")
    assert np.abs(albedo.reshape(-1, 3).mean(0) - tile.reshape(-1, 3).mean(0)).max() < 4.0     # the tile, repeated
    assert normal[..., 0].mean() > 200 and abs(normal[..., 2].mean() - 128) < 12              # +Z out (BGR: B = z)
    assert "metallicRoughnessTexture" in pbr
    written = sorted(os.listdir(out / "textures"))                    # USD: the images beside it
    assert [n for n in written if "Bark" in n] == ["Tree_video_Bark_albedo.png", "Tree_video_Bark_normal.png",
                                                   "Tree_video_Bark_roughness.png"]


def glb_array(doc, binary, index) -> np.ndarray:
    """Accessor ``index`` of a GLB as the glTF 2.0 specification (§3.6 Accessors) lays it out: its
    componentType (5121/5123/5125 unsigned 8/16/32-bit, 5126 float32) and type (SCALAR, VEC2-4) over
    its bufferView's bytes, ``byteStride`` or tightly packed."""
    a = doc["accessors"][index]
    dtype = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}[a["componentType"]]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
    view = doc["bufferViews"][a["bufferView"]]
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    item = np.dtype(dtype).itemsize * width
    stride = view.get("byteStride", item)
    rows = np.frombuffer(binary, np.uint8, stride * (a["count"] - 1) + item, start)
    rows = np.lib.stride_tricks.as_strided(rows, (a["count"], item), (stride, 1))
    return np.ascontiguousarray(rows).view(dtype).reshape(a["count"], width)


def test_moss_grows_on_the_branches_upper_side_in_the_glb(tmp_path):
    """The glTF carries the moss where it grows: read back (positions, normals, UVs, indices, the
    base colour image) from the GLB alone, the faces whose normal points up (glTF's +Y, > 0.5) show
    moss by colour at least 3 × as often as the faces that point down (< −0.5). The FBX (its
    embedded image, re-imported) and the USD (its image beside it) carry the same image: its moss
    in the band of the tubes' upper side (u ≡ 0.5)."""
    photo, _, _ = bark_photo(5, moss_share=0.12)
    path = tmp_path / "bark.jpg"
    cv2.imwrite(str(path), photo)
    out = tmp_path / "mossy"
    code, err = run(VIDEO, "--outline", OUTLINE, "--out", out, *QUICK, "--gltf", "--fbx", "--usd", "--bark-image",
                    path, "--moss", "1", "--bark-scale", "40")
    assert code == 0, err
    doc, binary = read_glb(out / "tree.glb")
    bark = next(i for i, m in enumerate(doc["materials"]) if "Bark" in m["name"])
    pbr = doc["materials"][bark]["pbrMetallicRoughness"]
    albedo = glb_image(doc, binary, doc["textures"][pbr["baseColorTexture"]["index"]]["source"])
    moss, _ = moss_lichen(albedo)
    H, W = moss.shape
    up, seen = [], []
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            if prim.get("material") != bark:
                continue
            tri = glb_array(doc, binary, prim["indices"]).reshape(-1, 3)
            normal = glb_array(doc, binary, prim["attributes"]["NORMAL"])
            uv = glb_array(doc, binary, prim["attributes"]["TEXCOORD_0"])
            n = normal[tri].mean(axis=1)
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            c = uv[tri].mean(axis=1)                  # glTF UV: (0, 0) the image's top-left, repeating
            col = np.floor(np.mod(c[:, 0], 1.0) * W).astype(int)
            row = np.floor(np.mod(c[:, 1], 1.0) * H).astype(int)
            up.append(n[:, 1])
            seen.append(moss[row, col])
    up, seen = np.concatenate(up), np.concatenate(seen)
    top, bottom = seen[up > 0.5].mean(), seen[up < -0.5].mean()
    print(f"\nGLB moss: {100 * top:.1f} % of the {int((up > 0.5).sum())} upward faces, {100 * bottom:.1f} % of the "
          f"{int((up < -0.5).sum())} downward ones; {100 * moss.mean():.1f} % of the texture")
    assert (up > 0.5).sum() > 50 and (up < -0.5).sum() > 50
    assert top > 0.1 and top >= 3.0 * bottom

    def band(bgr):                                  # moss share of the upper side's columns, the underside's
        seen = moss_lichen(bgr)[0]
        w = up_weight(seen.shape[1])
        return seen[:, w > 0.85].mean(), seen[:, w < 0.15].mean()
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.fbx(filepath=str(out / "tree.fbx"))
    imported = next(m for m in bpy.data.materials if "Bark" in m.name)
    bsdf = next(n for n in imported.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    image = bsdf.inputs["Base Color"].links[0].from_node.image
    rgba = np.array(image.pixels[:], np.float32).reshape(image.size[1], image.size[0], 4)[::-1]   # rows bottom-up
    fbx_bgr = np.clip(np.rint(rgba[..., 2::-1] * 255), 0, 255).astype(np.uint8)
    usd_bgr = cv2.imread(str(out / "textures" / "Tree_video_Bark_albedo.png"))
    for name, bgr in (("GLB", albedo), ("FBX", fbx_bgr), ("USD", usd_bgr)):
        hi, lo = band(bgr)
        print(f"{name} image: moss on {100 * hi:.1f} % of the upper side's columns, {100 * lo:.1f} % of the underside's")
        assert hi > 0.1 and hi >= 5.0 * lo


def test_a_bad_bark_photo_is_one_line(tmp_path):
    tiny = tmp_path / "tiny.png"
    cv2.imwrite(str(tiny), np.full((40, 40, 3), 90, np.uint8))
    for photo, needle in ((tmp_path / "none.jpg", "does not exist"), (tiny, "at least 160 px")):
        out = tmp_path / f"out_{photo.stem}"
        code, err = run(VIDEO, "--outline", OUTLINE, "--out", out, *QUICK, "--bark-image", photo)
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert code == 2 and len(lines) == 1 and needle in lines[0], err
        assert not out.exists()


def test_the_trunk_in_frame_1_is_the_bark_photo(tmp_path):
    """``--bark-image video``: the tile is made from frame 1's trunk (its mean colour within 12 of
    the true trunk's pixels in frame 1, CIELAB ΔE); without a video it is refused in one line."""
    from tree_from_video.core.topology import trunk_chain

    from samples import load_truth
    out = tmp_path / "own"
    code, err = run(VIDEO, "--outline", OUTLINE, "--out", out, *QUICK, "--bark-image", "video")
    assert code == 0, err
    assert json.loads((out / "bark.json").read_text())["photos"] == ["video"]
    tile = cv2.imread(str(out / "bark_albedo.png"))
    truth = load_truth(committed("broad"))
    cap = cv2.VideoCapture(VIDEO)
    ok, frame = cap.read()
    cap.release()
    assert ok
    chain = trunk_chain(truth["parents"])
    pts = truth["nodes2d_image"][0][chain]
    mask = np.zeros(frame.shape[:2], np.uint8)
    for a, b, r in zip(pts[:-1], pts[1:], truth["radius"][chain]):
        cv2.line(mask, tuple(np.round(a).astype(int)), tuple(np.round(b).astype(int)), 1,
                 max(int(round(0.7 * 2 * float(r))), 1))
    lab = lambda img: cv2.cvtColor(img.astype(np.uint8)[None], cv2.COLOR_BGR2LAB)[0].astype(float)  # noqa: E731
    want = lab(frame[mask > 0].mean(0, keepdims=True))[0]
    got = lab(tile.reshape(-1, 3).mean(0, keepdims=True))[0]
    print(f"trunk's mean Lab {np.round(want, 1)}, the tile's {np.round(got, 1)}: ΔE {np.linalg.norm(want - got):.1f}")
    assert np.linalg.norm(want - got) <= 12.0
    code, err = run("--generate", "1", "--species", "broad", "--out", tmp_path / "gen", "--bark-image", "video")
    assert code == 2 and "--bark-image video" in err and len(err.strip().splitlines()) == 1


def test_a_species_keeps_its_bark(tmp_path):
    """``VIDEO --generate --bark-image`` writes species.json with its bark beside it; trees grown
    later from that file (no --bark-image) carry that bark in their GLB; its maps gone: one line."""
    photo, _, _ = bark_photo(9)
    path = tmp_path / "bark.jpg"
    cv2.imwrite(str(path), photo)
    src = tmp_path / "src"
    code, err = run(VIDEO, "--outline", OUTLINE, "--out", src, *QUICK, "--bark-image", path, "--generate", "1",
                    "--seconds", "1", "--nodes", "80")
    assert code == 0, err
    doc = json.loads((src / "species.json").read_text())
    assert doc["bark"] == {"dir": "."}
    out = tmp_path / "grown"
    code, err = run("--generate", "1", "--species", src / "species.json", "--seconds", "1", "--nodes", "80",
                    "--no-leaves", "--gltf", "--out", out, "--quiet")
    assert code == 0, err
    glb, binary = read_glb(out / "tree_000" / "tree.glb")
    bark = next(m for m in glb["materials"] if "Bark" in m["name"])
    albedo = glb_image(glb, binary, glb["textures"][bark["pbrMetallicRoughness"]["baseColorTexture"]["index"]]["source"])
    tile = cv2.imread(str(src / "bark_albedo.png"))
    print(f"grown tree's bark mean {albedo.reshape(-1, 3).mean(0).round(1)}, "
          f"the species' tile {tile.reshape(-1, 3).mean(0).round(1)}")
    assert np.abs(albedo.reshape(-1, 3).mean(0) - tile.reshape(-1, 3).mean(0)).max() < 4.0
    os.unlink(src / "bark_normal.png")
    code, err = run("--generate", "1", "--species", src / "species.json", "--out", tmp_path / "bad")
    assert code == 2 and "bark_normal.png" in err and len(err.strip().splitlines()) == 1


def test_several_bark_photos_say_where_their_relief_came_from(tmp_path):
    """A folder of two shots of the same bark: their relief from parallax (bark.json), no warning;
    two photos of different bark: one warning line that they do not overlap, in the report too."""
    a, b, _, _ = bark_pair(44, move=(3.0, -1.0, 0.0))
    same = tmp_path / "same"
    same.mkdir()
    cv2.imwrite(str(same / "1.jpg"), a)
    cv2.imwrite(str(same / "2.jpg"), b)
    other = tmp_path / "other.jpg"
    cv2.imwrite(str(other), bark_photo(45)[0])
    for name, photos in (("pair", [same]), ("apart", [same / "1.jpg", other])):
        out = tmp_path / name
        args = [a for p in photos for a in ("--bark-image", p)]
        code, err = run(VIDEO, "--outline", OUTLINE, "--out", out, *QUICK, *args)
        assert code == 0, err
        said = json.loads((out / "bark.json").read_text())["height_from"]
        warned = [ln for ln in err.splitlines() if "do not overlap" in ln]
        report = check_report(out)
        print(f"\n{name}: {said}; {warned}")
        if name == "pair":
            assert [s.split(":")[0] for s in said] == ["stereo with photo 2", "stereo with photo 1"] and not warned
        else:
            assert said == ["shading", "shading"] and len(warned) == 1 and warned[0].startswith("warning: the 2 bark")
            assert sum("do not overlap" in w for w in report["warnings"]) == 1
