"""GUI check of the non-blocking Reconstruct (INVOKE): it must return at once, report progress while
Blender keeps redrawing, and end with the tree in the scene. Prints lines the test greps."""
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import register_with_sample  # noqa: E402

props = register_with_sample()
props.collection_name = "Modal Tree"
CANCEL = "--cancel" in sys.argv
state = {"t0": None, "seen": set(), "ticks": 0, "status_bar": False}
from tree_from_video.operators import jobs  # noqa: E402  (registered above)


def start():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    with bpy.context.temp_override(window=win, area=area):
        t = time.monotonic()
        result = bpy.ops.tree_video.reconstruct("INVOKE_DEFAULT")
        print(f"invoke returned {result} after {time.monotonic() - t:.2f} s", flush=True)
    state["t0"] = time.monotonic()
    bpy.app.timers.register(watch, first_interval=0.05)
    return None


def watch():
    wm = bpy.context.window_manager
    state["ticks"] += 1                      # the UI thread keeps running timers: Blender is responsive
    if wm.tree_video_status:
        state["seen"].add(wm.tree_video_status.split()[0])
        state["status_bar"] |= jobs.status_bar_shown()         # the job's progress in the status bar
        if CANCEL and wm.tree_video_progress > 10 and "cancel_sent" not in state:
            state["cancel_sent"] = time.monotonic()
            wm["tree_video_cancel"] = True
            print(f"cancel requested at {wm.tree_video_progress:.0f}% ({wm.tree_video_status})", flush=True)
        return 0.05
    if time.monotonic() - state["t0"] < 0.5:
        return 0.05
    coll = bpy.data.collections.get("Modal Tree")
    print(f"stages seen: {sorted(state['seen'])}; timer ticks while running: {state['ticks']}", flush=True)
    print(f"status bar: shown while running {state['status_bar']}, after {jobs.status_bar_shown()}", flush=True)
    if CANCEL:
        print(f"after cancel: collection {'present' if coll else 'absent'}, objects {len(bpy.data.objects)}, "
              f"stopped {time.monotonic() - state.get('cancel_sent', time.monotonic()):.2f} s after the request", flush=True)
    else:
        print(f"finished: collection {'present' if coll else 'absent'} with "
              f"{len(coll.objects) if coll else 0} objects (rig, branches, leaves): "
              f"{sorted(o.name for o in coll.objects) if coll else []}", flush=True)
    print("DONE", flush=True)
    return None


bpy.app.timers.register(start, first_interval=1.0)
