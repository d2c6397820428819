"""GUI run (issue 36 part 3, tree-cuts): in the real Blender, a limb of the broad sample's true tree
(left) is saved with Save Cut; Generate Tree grows a new broad tree (middle, seed 5), then the same
tree again with the Cut set (right): the limb placed where its base fits, the branches in its way
grown elsewhere. The cut's polygons are painted red. The sidebar's Tree tab shows the Generate
panel with the Cut file and the Save Cut / Place Cut buttons. For the README.

    real-blender gui-shot OUT.png --size 1600x900 --wait 30 -- \
        blender --factory-startup --python tests/gui/cut_shot.py
"""
import os
import sys
import tempfile

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import empty_stage, open_tree_tab  # noqa: E402

props = empty_stage()
from tree_from_video.operators.cut_op import select_bones  # noqa: E402
from tree_from_video.operators.scene import build, stored  # noqa: E402

from trees import broad_tree  # noqa: E402

LIMB = "B040"
tree = broad_tree(48)
src = build.build_tree(bpy.context, tree, "Source", bark="rough", leaves=False)
stored.store_tree(src["collection"], tree, "/videos/broad.mp4")
bpy.context.view_layer.objects.active = src["armature"]
select_bones(src["armature"], [LIMB])
path = os.path.join(tempfile.mkdtemp(), "limb.npz")
print("save cut:", bpy.ops.tree_video.save_cut(filepath=path), flush=True)
props.gen_cut = ""                                  # first the tree without it

props.species_source, props.species_name, props.envelope_source = "LIBRARY", "broad", "CIRCLE"
props.gen_height, props.gen_nodes, props.gen_seed, props.gen_frames = 7.0, 220, 5, 48
props.build_leaves = False
bpy.context.scene.cursor.location = (5.5, 0.0, 0.0)
print("generate:", bpy.ops.tree_video.generate(), flush=True)
props.gen_cut = path
bpy.context.scene.cursor.location = (11.0, 0.0, 0.0)
print("generate with the cut:", bpy.ops.tree_video.generate(), flush=True)
grown = next(c for c in bpy.data.collections if stored.grown_cuts(c))
info = stored.kept_tree(grown).meta["cuts"][0]
print(f"cut placed: {info}", flush=True)


def paint(coll, names) -> int:
    """The polygons of ``coll``'s branch mesh on the bones ``names`` get a red material; their count."""
    ob = next(o for o in coll.objects if o.type == "MESH")
    red = bpy.data.materials.get("Cut") or bpy.data.materials.new("Cut")
    red.diffuse_color = (0.85, 0.08, 0.05, 1.0)
    ob.data.materials.append(red)
    slot = len(ob.data.materials) - 1
    groups = {g.index for g in ob.vertex_groups if g.name in names}
    on = [any(g.group in groups and g.weight > 0.5 for g in v.groups) for v in ob.data.vertices]
    n = 0
    for p in ob.data.polygons:
        if all(on[i] for i in p.vertices):
            p.material_index = slot
            n += 1
    return n


cut_src = {f"B{n:03d}" for n in stored.kept_tree(src["collection"]).parents.nonzero()[0]
           if n in set(__import__("numpy").load(path)["source_nodes"][1:].tolist())}
cut_new = {f"B{n:03d}" for n in range(info["first_node"], info["first_node"] + info["bones"])}
print(f"painted: source {paint(src['collection'], cut_src)}, grown {paint(grown, cut_new)} polygons", flush=True)
for ob in bpy.context.selected_objects:
    ob.select_set(False)

# show the Generate sub-panel: start the reconstruction sub-panels closed (screenshot only)
from tree_from_video.ui import panel  # noqa: E402

for cls in (panel.TREE_PT_source, panel.TREE_PT_outline, panel.TREE_PT_reconstruction, panel.TREE_PT_output):
    bpy.utils.unregister_class(cls)
    cls.bl_options = {"DEFAULT_CLOSED"}
    bpy.utils.register_class(cls)


def view(space, r3d):
    space.shading.color_type = "MATERIAL"
    space.shading.light = "STUDIO"
    space.overlay.show_overlays = False
    r3d.view_perspective = "PERSP"
    r3d.view_rotation = (0.74, 0.67, 0.0, 0.0)
    r3d.view_location = (7.4, 0.0, 3.4)
    r3d.view_distance = 20.5


bpy.app.timers.register(open_tree_tab(view, frame=1), first_interval=1.0)
