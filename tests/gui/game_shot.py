"""GUI set-up for a screenshot of the Game Export panel and a game tree: register the add-on from
the repo, pick the Unreal preset, generate a tree of the bundled "broad" species (LODs, a 64-bone
rig, collision capsules drawn as wire), open the sidebar on the "Tree" tab with Game Export open.

    real-blender gui-shot docs/game.png --size 1600x1000 -- blender --factory-startup --python tests/gui/game_shot.py
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import open_tree_tab, register_with_sample  # noqa: E402

props = register_with_sample()
for ob in list(bpy.data.objects):
    bpy.data.objects.remove(ob)
props.game_engine = "UNREAL"
props.species_source, props.species_name = "LIBRARY", "broad"
props.envelope_source = "CIRCLE"
props.gen_nodes, props.gen_frames, props.gen_height = 160, 48, 8.0
props.loop_seconds = 1.5
print("generate:", bpy.ops.tree_video.generate("EXEC_DEFAULT"), flush=True)
coll = next(c for c in bpy.data.collections if c.name.startswith("broad"))
meshes = sorted(o.name for o in coll.all_objects if o.type == "MESH")
rig = next(o for o in coll.all_objects if o.type == "ARMATURE")
kept = sorted(coll.get("_tree_video_engine_files", {}).keys())
print(f"game tree: {len(rig.data.bones)} bones; {', '.join(n for n in meshes if '_LOD' in n)}; "
      f"{sum(n.startswith('UCP_') for n in meshes)} capsules; engine files {kept}", flush=True)

from tree_from_video.ui import panel  # noqa: E402

for cls in (panel.TREE_PT_source, panel.TREE_PT_outline, panel.TREE_PT_reconstruction, panel.TREE_PT_output,
            panel.TREE_PT_generate):
    bpy.utils.unregister_class(cls)
    cls.bl_options = {"DEFAULT_CLOSED"}
    bpy.utils.register_class(cls)
bpy.utils.unregister_class(panel.TREE_PT_game)
panel.TREE_PT_game.bl_options = set()
bpy.utils.register_class(panel.TREE_PT_game)


def game_view(space, r3d):
    space.shading.color_type = "TEXTURE"
    r3d.view_perspective = "PERSP"
    r3d.view_rotation = (0.82, 0.55, 0.08, 0.12)
    r3d.view_location = (0.0, 0.0, 4.0)
    r3d.view_distance = 16.0


bpy.app.timers.register(open_tree_tab(game_view, frame=10), first_interval=1.0)
