"""The web viewer plays the game export in a real browser (issue 33 item 6): Debian's chromium,
headless, WebGL through SwiftShader, driven by puppeteer-core. On a generated tree (held-out seed)
cut to a 2 s loop, 32 bones and two LODs: two frames differ where the tree moves; the skinned GLB's
silhouette matches Blender's render of the same frame from the same orthographic front camera
(IoU ≥ 0.9); the bone texture drives the same mesh to the skinned silhouette (IoU ≥ 0.97); the
Khronos validator finds no error in the game GLB nor in a film GLB; ``--viewer``'s page is written
with three.js beside it and its import map resolves to files that exist."""
import json
import math
import os
import re

import bpy
import cv2
import numpy as np
import pytest
import report
from browser import render_viewer, validate_glb

from tree_from_video import api
from tree_from_video.core.asset.game import GameSettings
from tree_from_video.operators.scene import outputs

from trees import empty_scene  # noqa: F401  (autouse fixture)

pytestmark = [pytest.mark.browser]
#: pixels of both renders (at 256 a leaf card is 1–2 px and the two samplers' cut-outs differ: 0.87)
SIZE = 512


def blender_silhouette(path: str, frame: int, ortho: tuple[float, float, float]) -> np.ndarray:
    """``(SIZE, SIZE)`` bool: Blender's Workbench render of scene frame ``frame + 1`` from an
    orthographic camera looking along Blender's +Y (glTF's −Z), centred at glTF ``(cx, cy)`` =
    Blender ``(cx, ·, cy)``, ``2·half`` metres high; leaf cards cut out by their texture's alpha."""
    cx, cy, half = ortho
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Front", bpy.data.cameras.new("Front"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 2 * half
    cam.data.clip_end = 1000.0
    cam.location = (cx, -100.0, cy)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    r = scene.render
    r.engine = "BLENDER_WORKBENCH"
    r.film_transparent = True
    r.resolution_x = r.resolution_y = SIZE
    r.resolution_percentage = 100
    r.image_settings.file_format = "PNG"
    r.image_settings.color_mode = "RGBA"
    scene.display.shading.light = "FLAT"
    scene.display.shading.color_type = "TEXTURE"
    scene.display.render_aa = "OFF"              # one sample a pixel, as the browser's canvas (no MSAA)
    scene.frame_set(frame + 1)
    r.filepath = path
    bpy.ops.render.render(write_still=True)
    return cv2.imread(path, cv2.IMREAD_UNCHANGED)[..., 3] > 127


def _mask(path) -> np.ndarray:
    return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)[..., 3] > 127


def _iou(a, b) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def test_the_viewer_plays_the_export_in_chromium(tmp_path):
    tree, = api.generate("broad", node_budget=120, n_frames=72, seed=81)
    game = GameSettings(bones=32, lods=2, bone_texture=True, viewer=True)
    out = tmp_path / "export"
    out.mkdir()
    outputs.write_outputs(tree, str(out), {"gltf": True}, fresh_scene=False, report=lambda m: None, loop_s=2.0,
                          game=game)
    # the front camera both sides use: the rest pose's box in the front view, with a margin
    rest = tree.nodes3d[0].astype(np.float64)
    lo, hi = rest.min(0), rest.max(0)
    cx, cy = 0.5 * (lo[0] + hi[0]), 0.5 * (lo[2] + hi[2])
    half = 0.62 * max(hi[2] - lo[2], hi[0] - lo[0])
    ortho = (cx, cy, half)
    doc = json.load(open(out / "bone_anim.json"))
    F = doc["frame_count"]
    a, b = 0, F // 2
    shots = render_viewer(tmp_path, out, SIZE, ortho, [f"skin:{a}", f"skin:{b}", f"texture:{a}", f"texture:{b}"])
    assert "SwiftShader" in shots["renderer"], shots["renderer"]
    skin_a, skin_b = _mask(tmp_path / f"skin_{a}.png"), _mask(tmp_path / f"skin_{b}.png")
    tex_a, tex_b = _mask(tmp_path / f"texture_{a}.png"), _mask(tmp_path / f"texture_{b}.png")
    assert skin_a.mean() > 0.05, "the viewer drew (almost) nothing"
    moved = (skin_a ^ skin_b).sum()
    assert moved > 0.02 * skin_a.sum(), f"frames {a} and {b} differ in {moved} pixels only"
    blender_a = blender_silhouette(str(tmp_path / "blender.png"), a, ortho)
    blender_b = blender_silhouette(str(tmp_path / "blender_b.png"), b, ortho)
    assert _iou(skin_a, blender_a) >= 0.9, f"skinned vs Blender, frame {a}: IoU {_iou(skin_a, blender_a):.3f}"
    assert _iou(skin_b, blender_b) >= 0.9, f"skinned vs Blender, frame {b}: IoU {_iou(skin_b, blender_b):.3f}"
    # the motion shows: Blender's own two frames differ where the browser's do
    assert _iou(skin_a ^ skin_b, blender_a ^ blender_b) > 0.3
    assert _iou(tex_a, skin_a) >= 0.97 and _iou(tex_b, skin_b) >= 0.97, (_iou(tex_a, skin_a), _iou(tex_b, skin_b))
    report.add("Web viewer (chromium, SwiftShader)", [
        f"{shots['renderer']}",
        f"skinned GLB vs Blender, frames {a}/{b}: IoU {_iou(skin_a, blender_a):.3f} / {_iou(skin_b, blender_b):.3f}",
        f"bone texture vs skinned: IoU {_iou(tex_a, skin_a):.4f} / {_iou(tex_b, skin_b):.4f}"])
    # the page users open: its import map points at files written beside it
    page = (out / "viewer.html").read_text()
    imports = json.loads(re.search(r'<script type="importmap">(.*?)</script>', page, re.S).group(1))["imports"]
    assert os.path.isfile(out / imports["three"]) and os.path.isfile(out / imports["three/addons/"] / "loaders/GLTFLoader.js")
    assert (out / "viewer" / "viewer.js").is_file() and "http" not in "".join(imports.values())
    checked, = validate_glb(out / "tree.glb")
    assert checked["errors"] == 0, checked["messages"]


def test_film_glb_validates(tmp_path):
    tree, = api.generate("conifer", node_budget=80, n_frames=24, seed=82)
    written = outputs.write_outputs(tree, str(tmp_path), {"gltf": True}, fresh_scene=False, report=lambda m: None)
    checked, = validate_glb(written["gltf"])
    assert checked["errors"] == 0, checked["messages"]
