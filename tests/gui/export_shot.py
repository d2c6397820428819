"""GUI run of the Export sub-panel as a user meets it: a generated tree and a small forest, two forest
trees selected, Export started as a click starts it (INVOKE: a modal job, one tree per timer tick),
then the sidebar on the "Tree" tab with only Export open. Prints lines CI greps.

    real-blender gui-shot docs/export.png --size 1600x900 --wait 12 -- blender --factory-startup --python tests/gui/export_shot.py
    (``-- --dialog``: then the File › Export › Tree from Video dialog, the list picking the generated tree)
"""
import os
import shutil
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import open_tree_tab, register_with_sample  # noqa: E402

OUT = "/tmp/tfv_export_shot"
DIALOG = "--dialog" in sys.argv
shutil.rmtree(OUT, ignore_errors=True)
props = register_with_sample()
for ob in list(bpy.data.objects):          # an empty stage for the trees
    bpy.data.objects.remove(ob)
props.species_source, props.species_name = "LIBRARY", "broad"
props.gen_nodes, props.gen_frames, props.gen_height = 120, 24, 8.0
print("tree:", bpy.ops.tree_video.generate("EXEC_DEFAULT"), flush=True)
props.forest_count, props.forest_spacing, props.forest_width, props.forest_depth = 3, 9.0, 24.0, 12.0
bpy.context.scene.cursor.location = (0.0, 14.0, 0.0)
print("forest:", bpy.ops.tree_video.generate_forest("EXEC_DEFAULT"), flush=True)
for name in ("Forest 000", "Forest 001"):   # the user clicks two trees of the forest
    for ob in bpy.data.collections[name].objects:
        ob.select_set(True)
props.export_format, props.output_dir = "GLB", OUT

# only the Export sub-panel open (screenshot only): re-register the sub-panels in their order
from tree_from_video.ui import panel  # noqa: E402

subs = [c for c in panel.classes if getattr(c, "bl_parent_id", "") == "TREE_PT_main"]
for cls in reversed(subs):
    bpy.utils.unregister_class(cls)
for cls in subs:
    cls.bl_options = set() if cls is panel.TREE_PT_export else {"DEFAULT_CLOSED"}
    bpy.utils.register_class(cls)

state = {"seen": [], "t0": None}


def view(space, r3d):
    space.shading.color_type = "TEXTURE"
    r3d.view_perspective = "PERSP"
    r3d.view_rotation = (0.82, 0.55, 0.08, 0.12)
    r3d.view_location = (0.0, 8.0, 4.0)
    r3d.view_distance = 40.0


def start_export():
    if bpy.context.window_manager.windows[0].screen is None:
        return 0.3
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    with bpy.context.temp_override(window=win, area=area):
        print("export enabled:", bpy.ops.tree_video.export.poll(), flush=True)
        t = time.monotonic()
        result = bpy.ops.tree_video.export("INVOKE_DEFAULT")
    print(f"export invoke returned {result} after {time.monotonic() - t:.2f} s", flush=True)
    state["t0"] = time.monotonic()
    # the redraws while it runs (issue 32: an export froze Blender for 6-21 s a tree): a draw
    # handler stamps every viewport draw, a timer asks for one every 0.1 s (a progress display's
    # rate; at 50 Hz software GL took the CPU the exports need)
    state["draws"] = []
    state["handler"] = bpy.types.SpaceView3D.draw_handler_add(lambda: state["draws"].append(time.monotonic()),
                                                              (), "WINDOW", "POST_PIXEL")
    state["area"] = area
    bpy.app.timers.register(watch, first_interval=0.02)
    return None


def watch():
    wm = bpy.context.window_manager
    status = wm.tree_video_status
    state["area"].tag_redraw()
    if status:
        if not state["seen"] or state["seen"][-1][0] != status:
            state["seen"].append((status, round(wm.tree_video_progress)))
            state.setdefault("when", []).append(round(time.monotonic() - state["t0"], 2))
        return 0.1
    if time.monotonic() - state["t0"] < 0.5:
        return 0.1
    print(f"export stages seen: {state['seen']}", flush=True)
    bpy.types.SpaceView3D.draw_handler_remove(state["handler"], "WINDOW")
    stamps = [state["t0"]] + [t for t in state["draws"] if t >= state["t0"]] + [time.monotonic()]
    gaps = [b - a for a, b in zip(stamps, stamps[1:])]
    gap = max(gaps)
    at = stamps[gaps.index(gap)] - state["t0"]
    print(f"export: longest gap starts {at:.2f} s in; stages began at {state.get('when')}", flush=True)
    print(f"export: {len(stamps) - 2} viewport draws in {stamps[-1] - stamps[0]:.1f} s, longest gap {gap:.2f} s", flush=True)
    print(f"redraw gaps under 1 s: {gap < 1.0}", flush=True)
    files = sorted(os.listdir(OUT)) if os.path.isdir(OUT) else []
    print(f"export written: {files}", flush=True)
    bpy.app.timers.register(open_tree_tab(view, frame=20), first_interval=0.1)
    if DIALOG:
        bpy.app.timers.register(open_dialog, first_interval=1.0)
    return None


def open_dialog():
    """File › Export › Tree from Video: the same settings in a dialog."""
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    if next(r for r in area.regions if r.type == "UI").active_panel_category != "Tree":
        return 0.3                         # after the sidebar is on the Tree tab
    props.export_scope, props.export_tree = "PICK", bpy.data.collections["broad 0"]
    with bpy.context.temp_override(window=win, area=area):
        print("dialog:", bpy.ops.tree_video.export_dialog("INVOKE_DEFAULT"), flush=True)
    return None


bpy.app.timers.register(start_export, first_interval=1.5)
