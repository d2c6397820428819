"""Run inside a background Blender (``blender -b TREE.blend --python export_worker.py -- JSON``) by
:mod:`.export_process`: export the tree objects the file holds with this add-on's own writer
(:mod:`.export`), so the user's Blender keeps drawing while a tree is written.

``JSON``: ``{"root": the add-on's folder, "path": the parent's sys.path, "format": "FBX" | "GLB" |
"USD", "out": the file to write, "objects": the objects' names, "overwrite": bool}``. Exit 0 when
written; on bad input or a failed export one line ``TREE_VIDEO_ERROR: <message>`` and exit 2.
Only the standard library and bpy are imported before the add-on is loaded from ``root`` (by
``package_loader``, as ``batch.py`` loads it).
"""
import json
import sys

ERROR_PREFIX = "TREE_VIDEO_ERROR: "


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
    objects = []
    for name in args["objects"]:
        ob = bpy.data.objects.get(name)
        if ob is None:
            print(f"{ERROR_PREFIX}the tree's object '{name}' is missing from its copy; no file written", flush=True)
            return 2
        if scene.collection.objects.get(ob.name) is None:
            scene.collection.objects.link(ob)
        objects.append(ob)
    bpy.context.view_layer.update()
    writer = {"FBX": export.export_fbx, "GLB": export.export_gltf, "USD": export.export_usd}[args["format"]]
    try:
        writer(args["out"], objects, overwrite=bool(args.get("overwrite")))
    except (errors.InputError, export.ExportError) as exc:
        print(f"{ERROR_PREFIX}{exc}", flush=True)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(json.loads(sys.argv[sys.argv.index("--") + 1])))
