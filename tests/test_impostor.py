"""The impostor (core/asset/impostor.py, operators/scene/impostor.py; issue 33 item 3): the
hemi-octahedral directions cover the upper hemisphere and the shader's inverse finds each cell
again; in Blender, cells of the atlas match renders of LOD0 at rest from their direction by a camera
aimed with Blender's own track-to rotation (not the module's basis), in the atlas's row order; the
normal atlas holds unit normals facing the viewer on the trunk; the crossed-billboard card is the
last LOD (two quads on the horizon cells), alpha-tested in the GLB, and impostor.json lists every
direction."""
import json
import math

import bpy
import cv2
import numpy as np
import pytest
from mathutils import Vector
from test_exports import read_glb

from tree_from_video import api
from tree_from_video.core.asset import impostor as imp
from tree_from_video.operators.scene import build, export, trees

from trees import empty_scene  # noqa: F401  (autouse fixture)

pytestmark = [pytest.mark.blender]


def test_directions_cover_the_upper_hemisphere_and_invert():
    for n in (4, 8, 16):
        d = imp.grid_directions(n)
        assert np.allclose(np.linalg.norm(d, axis=-1), 1.0) and (d[..., 1] >= 0).all()
        j, i = np.mgrid[0:n, 0:n]
        assert np.array_equal(imp.direction_cell(d, n), np.stack([i, j], axis=-1))
    d = imp.grid_directions(8)
    assert d[3:5, 3:5, 1].min() > 0.9                      # the middle looks down from the zenith
    corners = d[[0, 0, -1, -1], [0, -1, 0, -1]]
    assert np.abs(corners[:, 1]).max() < 0.2                # the corners are near the horizon
    rng = np.random.default_rng(3)
    v = rng.normal(size=(500, 3))
    v[:, 1] = np.abs(v[:, 1])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    cells = imp.direction_cell(v, 8)
    nearest = d[cells[:, 1], cells[:, 0]]
    assert np.degrees(np.arccos(np.clip((nearest * v).sum(1), -1, 1))).max() < 30.0   # an 8×8 cell's reach


def _camera_render(layout, d_gltf, path) -> np.ndarray:
    """Alpha > 127 of a Workbench render along −d by a camera aimed with Blender's track-to quaternion."""
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Check", bpy.data.cameras.new("Check"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.data.type, cam.data.ortho_scale = "ORTHO", 2 * layout.radius
    cam.data.clip_end = 100.0
    d = Vector(imp.TO_GLTF.T @ d_gltf)
    cam.location = Vector(layout.centre) + d * 4 * layout.radius
    up = "Y"
    cam.rotation_mode = "QUATERNION"
    cam.rotation_quaternion = (-d).to_track_quat("-Z", up)
    if abs(d.z) > 0.999:                                     # the zenith: image up along world +Y
        cam.rotation_quaternion = Vector((0, 0, -1)).to_track_quat("-Z", "Y")
    r = scene.render
    r.engine, r.film_transparent = "BLENDER_WORKBENCH", True
    r.resolution_x = r.resolution_y = layout.cell
    r.image_settings.color_mode = "RGBA"
    scene.display.shading.light, scene.display.shading.color_type = "FLAT", "TEXTURE"
    scene.display.render_aa = "8"
    r.filepath = path
    bpy.ops.render.render(write_still=True)
    bpy.data.objects.remove(cam)
    return cv2.imread(path, cv2.IMREAD_UNCHANGED)[..., 3] > 127


def test_atlas_cells_are_the_views_and_the_card_is_the_last_lod(tmp_path):
    tree, = api.generate("sparse", node_budget=90, n_frames=6, seed=97)
    built = build.build_tree(bpy.context, tree, "Imp", bone_budget=24, lods=2, impostor=True)
    files = built["impostor"]
    assert sorted(files) == sorted(imp.FILES)
    albedo = cv2.imdecode(np.frombuffer(files["impostor_albedo.png"], np.uint8), cv2.IMREAD_UNCHANGED)
    normal = cv2.imdecode(np.frombuffer(files["impostor_normal.png"], np.uint8), cv2.IMREAD_UNCHANGED)[..., [2, 1, 0, 3]]
    doc = json.loads(files["impostor.json"])
    n, S = doc["grid"], doc["cell_px"]
    assert albedo.shape == (n * S, n * S, 4) and len(doc["directions"]) == n
    asset_pts = np.concatenate([m.co for m in (built["asset"].lods[0].branches, built["asset"].lods[0].leaves)])
    layout = imp.layout_for(asset_pts, n, S)
    assert np.allclose(doc["centre"], imp.TO_GLTF @ layout.centre, atol=1e-4)
    # the atlas's cells against the independent camera (the rig at rest, LOD0 only: the others hidden)
    rig = built["armature"]
    rig.data.pose_position = "REST"
    for ob in built["lods"][1:]:
        ob.hide_render = True
    for (j, i) in ((0, 0), (n // 2, n // 2), (n - 1, n // 2), (2, 5)):
        d = np.asarray(doc["directions"][j][i])
        want = _camera_render(layout, d, str(tmp_path / f"v{j}{i}.png"))
        got = albedo[j * S:(j + 1) * S, i * S:(i + 1) * S, 3] > 127
        iou = (want & got).sum() / (want | got).sum()
        assert iou >= 0.95, f"cell ({i}, {j}): IoU {iou:.3f} with the track-to camera's render"
    # normals: unit where covered; the trunk's face the viewer of a horizon cell
    cov = normal[..., 3] > 127
    nv = normal[..., :3].astype(np.float64) / 255.0 * 2 - 1
    assert np.abs(np.linalg.norm(nv[cov], axis=1) - 1).mean() < 0.05
    j, i = imp.direction_cell(np.array([0.0, 1e-3, 1.0]), n)                 # the front, on the horizon
    cell_n = nv[j * S:(j + 1) * S, i * S:(i + 1) * S][cov[j * S:(j + 1) * S, i * S:(i + 1) * S]]
    d = np.asarray(doc["directions"][j][i])
    assert np.mean(cell_n @ d > 0) > 0.6
    # the card: the last LOD, two quads, its UVs inside the two horizon cells
    card = built["lods"][-1]
    assert card.name == "Imp_LOD2" and len(card.data.polygons) == 2
    uv = np.empty(2 * len(card.data.loops), np.float32)
    card.data.uv_layers["UVMap"].data.foreach_get("uv", uv)
    uv = uv.reshape(2, 4, 2)                                   # per quad, its four corners
    cells = set()
    for quad in uv:
        mid = quad.mean(axis=0)
        i, j = int(mid[0] * n), int((1 - mid[1]) * n)
        cells.add((i, j))
        assert (quad[:, 0] >= i / n - 1e-6).all() and (quad[:, 0] <= (i + 1) / n + 1e-6).all()
        assert (1 - quad[:, 1] >= j / n - 1e-6).all() and (1 - quad[:, 1] <= (j + 1) / n + 1e-6).all()
        assert abs(doc["directions"][j][i][1]) < 0.25             # a view near the horizon
    assert len(cells) == 2
    rig.data.pose_position = "POSE"
    doc_glb, _ = read_glb(export.export_gltf(tmp_path / "imp.glb", trees.tree_objects(built["collection"])))
    mats = {m["name"]: m for m in doc_glb["materials"]}
    assert mats["Imp_LOD2 Impostor"]["alphaMode"] == "MASK" and mats["Imp Leaf"]["alphaMode"] == "MASK"
    assert "Imp_LOD2" in [m["name"] for m in doc_glb["meshes"]]
    assert math.isclose(sum(len(r) for r in doc["directions"]), n * n)
