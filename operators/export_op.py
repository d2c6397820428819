"""Export trees from the panel (Tree sidebar › Export, and File › Export › Tree from Video): the
selected trees, or the tree or forest picked from the file's trees, each to its own file named
after the tree (or the File Name typed for a single tree), as FBX, binary glTF or USD.

The export is a modal job (:class:`.jobs.SteppedJob`): the exporters are bpy operators, so they
run on the main thread, one tree per timer tick, with progress in the panel and the status bar
between trees and Esc / *Cancel*. Each file is written under a hidden temporary name and all are
renamed to their names only after the last tree: a cancelled or failed export writes no file and
leaves existing files as they were. ``EXEC_DEFAULT`` (scripts, tests) runs it all at once.
"""
from __future__ import annotations

import os
import time
import uuid

import bpy

from ..core.asset.game import fbx_options
from ..core.errors import InputError
from ..core.formats import by_key, interchange
from . import jobs
from .scene import export, export_process, game, provenance, trees

#: the last finished export (shown in the panel)
LAST_EXPORT = export.Exported()
#: characters a typed file name cannot hold (path separators, and those Windows refuses)
_UNSAFE = str.maketrans({c: "_" for c in '/\\:*?"<>|'})


# ----------------------------------------------------------------------------- what is exported

def targets(context, props) -> list:
    """The tree collections the export writes: the selected trees, or the picked tree / forest's trees."""
    if props.export_scope == "PICK":
        return trees.trees_in(props.export_tree)
    return trees.selected_trees(context)


def why_not(context, props) -> str | None:
    """Why the Export button is disabled (its poll message), or None if it can run."""
    if jobs.running():
        return "a job is running; wait for it to finish or press Cancel"
    if not trees.file_trees():
        return "no tree in this file; press Reconstruct, Generate Tree or Generate Forest first"
    if not targets(context, props):
        if props.export_scope == "PICK":
            return "no tree picked; choose one in the Tree list"
        return "no tree selected; click a tree in the viewport, or use Pick a Tree"
    return None


def export_folder(props) -> str:
    """The absolute export folder; a folder relative to an unsaved .blend is refused."""
    raw = props.output_dir.strip()
    if not raw:
        raise InputError("no export folder set; choose one in the Export panel")
    if raw.startswith("//") and not bpy.data.filepath:
        raise InputError(f"the folder '{raw}' is relative to the .blend file, which is not saved yet; "
                         "save the file or choose an absolute folder")
    folder = bpy.path.abspath(raw)
    if not os.path.isabs(folder):
        raise InputError(f"the folder '{raw}' is relative; choose an absolute folder, or one starting "
                         "with // (beside the saved .blend file)")
    return os.path.normpath(folder)


def file_names(colls, props) -> list:
    """File names (with extension) of the trees ``colls``: the typed File Name for a single tree,
    else each tree's name cleaned (``Oak 001`` → ``Oak_001``), made unique."""
    ext = by_key(props.export_format).extension
    typed = props.export_name.strip() if len(colls) == 1 else ""
    if typed.lower().endswith(ext):
        typed = typed[:-len(ext)]
    typed = typed.translate(_UNSAFE).strip(" .")
    if len(colls) == 1 and props.export_name.strip() and not typed:
        raise InputError(f"the file name '{props.export_name}' has no usable characters; type another name")
    names, seen = [], set()
    for coll in colls:
        base = typed or bpy.path.clean_name(coll.name) or "tree"
        name, k = base, 2
        while name.lower() in seen:
            name, k = f"{base}_{k}", k + 1
        seen.add(name.lower())
        names.append(name + ext)
    return names


def plan(context, props) -> list:
    """``[(tree collection, absolute path)]`` the export writes, or :class:`InputError` naming what
    is wrong (nothing to export, a relative folder in an unsaved file, no USD, a file that exists)."""
    colls = targets(context, props)
    if not colls:
        raise InputError(why_not(context, props) or "no tree to export")
    folder = export_folder(props)
    if by_key(props.export_format).needs_usd and not export.has_usd():
        raise InputError("this Blender was built without USD; export FBX or glTF instead")
    paths = [os.path.join(folder, name) for name in file_names(colls, props)]
    if not props.overwrite:
        extra = [p for coll, path in zip(colls, paths) for p in game.kept_paths(coll, path)
                 + list(provenance.kept_files(coll, path))]
        existing = [p for p in paths + extra if os.path.exists(p)]
        if existing:
            more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
            fix = "choose another name" if len(paths) == 1 else "choose another folder"
            raise InputError(f"{existing[0]} exists{more}: tick Overwrite or {fix}")
    return list(zip(colls, paths))


# ----------------------------------------------------------------------------- the sliced work

def _staging_path(path: str) -> str:
    root, ext = os.path.splitext(path)
    return os.path.join(os.path.dirname(path), f".{os.path.basename(root)}{ext}.{uuid.uuid4().hex[:8]}.part{ext}")


def _remove_quietly(path: str) -> None:
    try:
        os.remove(path)
    except OSError:
        pass


def _staged_tree(coll, path: str, name: str, staged: list) -> tuple[list, str]:
    """The tree's objects and the hidden staging file it is written to first (added to
    ``staged``); InputError if the tree was deleted meanwhile."""
    try:
        objects = trees.tree_objects(coll)
    except ReferenceError:
        raise InputError(f"the tree '{name}' was deleted during the export; no file written") from None
    tmp = _staging_path(path)
    staged.append((tmp, path))
    return objects, tmp


def _background(items, names: list[str], sizes: list[float], fmt: str, overwrite: bool,
                staged: list, running: list, total: float, seconds: list, fbx_extra: dict | None = None):
    """Yield ``(stage, fraction)`` every tick while background Blenders write ``items`` to staging
    files (the trees shared among :data:`.scene.export_process.PARALLEL` processes by size, each
    writing its trees one after another); ``staged`` gets (staging file, path) per tree and
    ``running`` the processes while they run, ``seconds`` each tree's export time as it is written.
    Raises InputError naming the tree that failed."""
    jobs = [_staged_tree(coll, path, name, staged) for (coll, path), name in zip(items, names)]
    games = [fmt == "GLB" and game.is_game_tree(coll) for coll, _ in items]
    parts = export_process.split(sizes)
    for k, part in enumerate(parts):        # one process started a tick (each copies its trees to a .blend)
        running.append([export_process.start(fmt, [jobs[i] for i in part], overwrite, fbx_extra,
                                             [games[i] for i in part]), part, 0])
        if k + 1 < len(parts):
            yield f"starting the background exports ({k + 1}/{len(parts)})", 0.0
    n, finished, so_far = len(items), 0, 0.0
    while running:
        for entry in list(running):
            proc, part, seen = entry
            code = proc.poll()                  # before done(): an exit then counts every line
            done = proc.done()
            for i, took in zip(part[seen:done], proc.seconds()[seen:done]):
                so_far += sizes[i]
                finished += 1
                seconds[i] = took
            entry[2] = done
            if code is None:
                continue
            running.remove(entry)
            failed = code != 0 or done < len(part) or not all(os.path.isfile(jobs[i][1]) for i in part)
            message = proc.error() if failed else None
            proc.cleanup()
            if message is not None:
                i = part[min(done, len(part) - 1)]
                raise InputError(f"'{names[i]}': {message.replace(jobs[i][1], items[i][1])}; no file written")
        if running:
            time.sleep(0.02)                # a tick's poll, not a busy loop (execute runs it straight)
            now = ", ".join(f"'{names[i]}'" for i in sorted(part[seen] for _, part, seen in running if seen < len(part)))
            yield (f"exporting {now} ({min(finished + 1, n)}/{n})" if now else
                   f"closing the background exports ({finished}/{n} written)"), so_far / total


def export_steps(items, fmt: str, overwrite: bool, made_folder: bool, background: bool | None = None,
                 fbx_extra: dict | None = None):
    """Generator for :class:`.jobs.SteppedJob`: exports tree by tree (``items`` from :func:`plan`)
    to temporary files, yielding ``(stage, fraction)`` before each (fraction by bones × frames),
    then renames them all to their paths; returns :class:`.scene.export.Exported`. Closing it early removes the
    temporary files (and the folder if it made it and it is empty). With ``background`` (default:
    :func:`.scene.export_process.available`, a GUI session) the trees are written by background
    Blenders (:data:`.scene.export_process.PARALLEL`, each writing its share one tree after
    another) and the generator yields every tick while they run, so the UI keeps drawing and Esc
    stops them. ``fbx_extra``: an engine preset's FBX options (:func:`core.asset.game.fbx_options`).
    A game tree's engine files (:mod:`.scene.game`) are staged and renamed with its file."""
    background = export_process.available() if background is None else background
    extra = {"extra": dict(fbx_extra)} if fmt == "FBX" and fbx_extra else {}
    writer = getattr(export, by_key(fmt).writer)
    names = [coll.name for coll, _ in items]
    sizes = [trees.tree_size(coll) for coll, _ in items]
    total, so_far = float(sum(sizes)), 0
    staged: list = []
    written: list = []
    folder = os.path.dirname(items[0][1])
    running: list = []                      # background exports: [process, its items, how many done]
    seconds = [0.0] * len(items)
    start = time.perf_counter()
    try:
        if background:
            yield f"exporting {len(items)} trees in the background", 0.0
            yield from _background(items, names, sizes, fmt, overwrite, staged, running, total, seconds,
                                   extra.get("extra"))
        else:
            for k, ((coll, path), name, size) in enumerate(zip(items, names, sizes)):
                yield f"exporting '{name}' ({k + 1}/{len(items)})", so_far / total
                objects, tmp = _staged_tree(coll, path, name, staged)
                t = time.perf_counter()
                try:
                    packed = {"game": True} if fmt == "GLB" and game.is_game_tree(coll) else {}
                    writer(tmp, objects, overwrite=overwrite, context=bpy.context, **extra, **packed)  # USD: textures/
                except (InputError, export.ExportError) as exc:
                    raise InputError(f"'{name}': {str(exc).replace(tmp, path)}; no file written") from None
                so_far += size
                seconds[k] = time.perf_counter() - t
        for coll, path in items:            # a game tree's engine files and a run's report beside its file
            stem = os.path.splitext(os.path.basename(path))[0]
            beside = {os.path.join(os.path.dirname(path), name): data for name, data in game.kept_files(coll, stem).items()}
            beside.update(provenance.kept_files(coll, path))
            for final, data in beside.items():
                tmp = _staging_path(final)
                staged.append((tmp, final))
                with open(tmp, "wb") as fh:
                    fh.write(data)
        if not overwrite:
            for _, path in staged:
                if os.path.exists(path):
                    raise InputError(f"{path} exists: tick Overwrite or choose another name; no file written")
        for tmp, path in staged:
            try:
                os.replace(tmp, path)
            except OSError as exc:
                done = f"; written: {', '.join(written)}" if written else "; no file written"
                raise InputError(f"cannot write '{path}' ({exc.strerror}); check the folder's permissions{done}") from None
            written.append(path)
        return export.Exported(written, seconds, time.perf_counter() - start)
    finally:
        for proc, *_ in running:            # cancelled or failed: stop the others, nothing written
            proc.cleanup()
        for tmp, _ in staged:
            if os.path.exists(tmp):
                _remove_quietly(tmp)
        if made_folder and not written:
            try:
                os.rmdir(folder)
            except OSError:
                pass


# ----------------------------------------------------------------------------- operators


# ----------------------------------------------------------------------------- the settings' layout

def _names(colls, limit: int = 3) -> str:
    shown = ", ".join(c.name for c in colls[:limit])
    return shown + (f" and {len(colls) - limit} more" if len(colls) > limit else "")


def draw_settings(layout, context, dialog: bool = False) -> None:
    """The export settings and what pressing Export will write (the Export sub-panel, and the
    File › Export › Tree from Video dialog, which has its own Export button)."""
    props = context.scene.tree_video
    layout.use_property_split = True
    layout.use_property_decorate = False
    col = layout.column()
    if not trees.file_trees():
        col.label(text="No tree in this file yet: Reconstruct or Generate one", icon="INFO")
    width = 440 if dialog or context.region is None else context.region.width / context.preferences.view.ui_scale
    chars = max(int((width - 70) / CHAR_PX), 20)
    if LAST_EXPORT.paths and not dialog:          # what the last export wrote comes first
        last = LAST_EXPORT.paths
        sub = col.box().column(align=True)
        sub.label(text=f"Last export: {len(last)} {'file' if len(last) == 1 else 'files'} in", icon="CHECKMARK")
        for line in _wrap(os.path.dirname(last[0]) + os.sep, chars):
            sub.label(text=line, icon="BLANK1")
        for path in last[:3]:
            sub.label(text=os.path.basename(path), icon="BLANK1")
        if len(last) > 3:
            sub.label(text=f"… and {len(last) - 3} more", icon="BLANK1")
        sub.label(text=LAST_EXPORT.timing(), icon="TIME")
    row = col.row()
    row.use_property_split = False
    row.prop(props, "export_scope", expand=True)
    if props.export_scope == "PICK":
        col.prop(props, "export_tree")
    colls = targets(context, props)
    if colls:
        col.label(text=f"{len(colls)} {'tree' if len(colls) == 1 else 'trees'}: {_names(colls)}",
                  icon="OUTLINER_OB_ARMATURE")
    elif props.export_scope == "SELECTED":
        col.label(text="Click a tree in the viewport, or Pick a Tree", icon="RESTRICT_SELECT_OFF")
    if len(colls) <= 1:
        col.prop(props, "export_name", placeholder=bpy.path.clean_name(colls[0].name) if colls else "")
    else:
        col.label(text="Files are named after each tree", icon="FILE")
    col.prop(props, "export_format")
    col.prop(props, "output_dir")
    col.prop(props, "overwrite")
    problem = None
    if colls:
        try:
            plan(context, props)
        except InputError as exc:
            problem = str(exc)
    if problem and any(p in problem for p in LAST_EXPORT.paths):
        # the next export would overwrite what the last one just wrote: a note, not an error
        col.label(text="Just written: tick Overwrite to redo", icon="INFO")
    elif problem:
        box = col.box().column(align=True)
        for k, line in enumerate(_wrap(problem, chars)):
            box.label(text=line, icon="ERROR" if k == 0 else "BLANK1")
    if not dialog:
        row = col.row()
        row.scale_y = 1.3
        n = len(colls)
        row.operator("tree_video.export", icon="EXPORT", text=f"Export {n} Trees" if n > 1 else "Export Tree")


#: px per character of a sidebar label (Blender's UI font at scale 1; 6.2 let long paths be cut short)
CHAR_PX = 7.5


def _wrap(text: str, width: int) -> list:
    """``text`` in lines of at most ``width`` characters (a label does not wrap)."""
    import textwrap
    return textwrap.wrap(text, width) or [""]


class TREE_OT_export(jobs.JobOperator, bpy.types.Operator):
    """Export the selected trees (or the tree picked in the Export panel), each to its own file in the export folder (Esc cancels)"""  # noqa: E501  (the tooltip)

    bl_idname = "tree_video.export"
    bl_label = "Export Tree"
    bl_options = {"REGISTER"}
    what = "export"
    cancelled_note = "no file written"

    @classmethod
    def poll(cls, context):
        props = getattr(context.scene, "tree_video", None)
        if props is None:
            return False
        reason = why_not(context, props)
        if reason:
            cls.poll_message_set(reason)
            return False
        return True

    def make_job(self, context):
        props = context.scene.tree_video
        items = plan(context, props)
        folder = os.path.dirname(items[0][1])
        made = not os.path.isdir(folder)
        try:
            os.makedirs(folder, exist_ok=True)
        except OSError as exc:
            raise InputError(f"cannot create the export folder '{folder}' ({exc.strerror}); "
                             "choose another folder") from None
        if not os.access(folder, os.W_OK):
            raise InputError(f"the export folder '{folder}' is not writable; choose another folder")
        engine = "" if props.game_engine == "NONE" else props.game_engine.lower()
        return jobs.SteppedJob(export_steps(items, props.export_format, props.overwrite, made,
                                            fbx_extra=fbx_options(engine)))

    def done(self, context, result):
        LAST_EXPORT.paths, LAST_EXPORT.seconds, LAST_EXPORT.total = result.paths, result.seconds, result.total
        paths = result.paths
        for path, took in zip(paths, result.seconds):
            print(f"tree_from_video: exported {path} ({took:.1f} s)", flush=True)
        if len(paths) == 1:
            self.report({"INFO"}, f"exported {paths[0]} ({result.timing()})")
        else:                   # one status line that fits: the count and the folder (the panel lists the files)
            folders = {os.path.dirname(p) for p in paths}
            where = f" to {folders.pop()}" if len(folders) == 1 else ""
            self.report({"INFO"}, f"exported {len(paths)} files{where} in {result.total:.0f} s (Export panel: Last export)")
        return {"FINISHED"}


class TREE_OT_export_dialog(bpy.types.Operator):
    """Export trees of this file: the selected trees or one picked from the list, FBX, glTF or USD"""

    bl_idname = "tree_video.export_dialog"
    bl_label = "Export Trees"

    @classmethod
    def poll(cls, context):
        if getattr(context.scene, "tree_video", None) is None:
            return False
        if not trees.file_trees():
            cls.poll_message_set("no tree in this file; press Reconstruct, Generate Tree or Generate Forest first")
            return False
        return not jobs.running()

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=440, title="Export Trees", confirm_text="Export")

    def draw(self, context):
        draw_settings(self.layout, context, dialog=True)

    def execute(self, context):
        reason = why_not(context, context.scene.tree_video)
        if reason:
            self.report({"ERROR"}, reason)
            return {"CANCELLED"}
        mode = "EXEC_DEFAULT" if bpy.app.background or context.window is None else "INVOKE_DEFAULT"
        result = bpy.ops.tree_video.export(mode)
        return {"CANCELLED"} if "CANCELLED" in result else {"FINISHED"}


def menu_export(self, context):
    exts = ", ".join(f.extension for f in interchange())
    self.layout.operator(TREE_OT_export_dialog.bl_idname, text=f"Tree from Video ({exts})")


classes = (TREE_OT_export, TREE_OT_export_dialog)

_register, _unregister = bpy.utils.register_classes_factory(classes)


def register():
    _register()
    bpy.types.TOPBAR_MT_file_export.append(menu_export)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    _unregister()
