"""GUI run (issue 32, item 3): a tree with the video's bark colour and rough bark (left) beside its GLB
re-imported into the same scene (right), in Material Preview; the viewport rendered
(``render.opengl``) and the two trunks' mean colours compared. Prints lines CI greps.

    real-blender gui-shot OUT.png --size 1400x900 --wait 35 -- \
        blender --factory-startup --python tests/gui/reimport_shot.py
"""
import os
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import empty_stage, material_view  # noqa: E402

empty_stage()
from tree_from_video.operators.scene import build, export  # noqa: E402

from trees import broad_tree  # noqa: E402

OUT = tempfile.mkdtemp(prefix="tfv_reimport_")
SHIFT = 6.0                                 # metres the re-imported tree stands to the right
tree = broad_tree(24)
tree.meta = {"bark_colour": {"colour": [0.45, 0.38, 0.3]}}
res = build.build_tree(bpy.context, tree, "Orig", bark="rough", leaves=False)
glb = export.export_gltf(os.path.join(OUT, "orig.glb"), [res["armature"], res["mesh"]])
before = set(bpy.data.objects)
bpy.ops.import_scene.gltf(filepath=glb)
for ob in set(bpy.data.objects) - before:
    if ob.parent is None:
        ob.location.x += SHIFT
for ob in bpy.data.objects:                 # only the two bark meshes show (the importer's bone shapes hidden)
    if ob.type != "MESH" or ob.name == "Icosphere":
        ob.hide_set(True)
print("re-imported bark:", [n.type for m in bpy.data.materials if m.name.startswith("Orig Bark.")
                            for n in m.node_tree.nodes if n.type == "TEX_IMAGE"], flush=True)


state = {"shown": False}


def compare():
    if bpy.context.window.screen is None:
        return 0.3
    area = next(a for a in bpy.context.window.screen.areas if a.type == "VIEW_3D")
    space = area.spaces.active
    if not state["shown"]:                # Material Preview first; rendered after a few redraws
        material_view(space, (SHIFT / 2, 0.0, 1.2), 5.0)
        state["shown"] = True
        return 8.0
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 700, 450
    path = os.path.join(OUT, "view.png")
    scene.render.filepath = path
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(area=area, region=region):
        bpy.ops.render.opengl(write_still=True, view_context=True)
    img = bpy.data.images.load(path)
    w, h = img.size
    px = np.array(img.pixels[:], np.float32).reshape(h, w, 4)[..., :3]
    bg = np.median(px.reshape(-1, 3), axis=0)
    bark = np.abs(px - bg).sum(-1) > 0.06              # what is not the viewport's backdrop
    left, right = bark.copy(), bark.copy()
    left[:, w // 2:] = False
    right[:, :w // 2] = False
    a, b = px[left].mean(0), px[right].mean(0)
    off = float(np.max(np.abs(b - a) / np.maximum(a, 1e-3)))
    print(f"bark pixels: original {left.sum()}, re-imported {right.sum()}; mean colour original "
          f"{np.round(a, 3).tolist()}, re-imported {np.round(b, 3).tolist()}; largest channel off {off:.1%}", flush=True)
    print(f"bark colours within 10%: {off <= 0.10 and left.sum() > 2000 and right.sum() > 2000}", flush=True)
    space.overlay.show_overlays = True
    print("ui ready", flush=True)
    return None


bpy.app.timers.register(compare, first_interval=1.0)
