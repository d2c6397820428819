"""Run inside a background Blender (``blender -b TREES.blend --python export_worker.py -- JSON``) by
:mod:`.export_process`: export the trees the file holds, one file each, in order, with this
add-on's own writer (:mod:`.export`), so the user's Blender keeps drawing while they are written.

``JSON``: ``{"root": the add-on's folder, "path": the parent's sys.path, "format": "FBX" | "GLB" |
"USD", "overwrite": bool, "jobs": [{"objects": a tree's object names, "out": its file}, ...]}``.
After each file one line ``TREE_VIDEO_DONE: <job index> <seconds it took>``; exit 0 when all are written; on bad
input or a failed export one line ``TREE_VIDEO_ERROR: <message>`` and exit 2 (the files before it
stay written: the caller removes them). Only the standard library and bpy are imported before the
add-on is loaded from ``root`` (by ``package_loader``, as ``batch.py`` loads it).
"""
import json
import sys
import time

ERROR_PREFIX = "TREE_VIDEO_ERROR: "
DONE_PREFIX = "TREE_VIDEO_DONE: "


def main(args: dict) -> int:
    import bpy
    for p in args["path"]:                       # the parent's: its wheels (numpy, OpenCV) too
        if p not in sys.path:
            sys.path.append(p)
    sys.path.insert(0, args["root"])             # the add-on's folder, loaded as the batch loads it
    from package_loader import load_module
    export = load_module("operators.scene.export")
    errors = load_module("core.errors")
    scene = bpy.context.scene
    writer = {"FBX": export.export_fbx, "GLB": export.export_gltf, "USD": export.export_usd}[args["format"]]
    for k, job in enumerate(args["jobs"]):
        objects = []
        for name in job["objects"]:
            ob = bpy.data.objects.get(name)
            if ob is None:
                print(f"{ERROR_PREFIX}the tree's object '{name}' is missing from its copy; no file written", flush=True)
                return 2
            if scene.collection.objects.get(ob.name) is None:
                scene.collection.objects.link(ob)
            objects.append(ob)
        bpy.context.view_layer.update()
        start = time.perf_counter()
        try:
            extra = {"extra": args["fbx_extra"]} if args["format"] == "FBX" and args.get("fbx_extra") else {}
            if args["format"] == "GLB" and job.get("game"):
                extra = {"game": True}
            writer(job["out"], objects, overwrite=bool(args.get("overwrite")), **extra)
        except (errors.InputError, export.ExportError) as exc:
            print(f"{ERROR_PREFIX}{exc}", flush=True)
            return 2
        print(f"{DONE_PREFIX}{k} {time.perf_counter() - start:.3f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(json.loads(sys.argv[sys.argv.index("--") + 1])))
