"""The modal-job base of the operators that run the core in a worker thread (Reconstruct, Track &
Preview, Generate Tree, Generate Forest) or main-thread work in slices (:class:`SteppedJob`: Export).

:class:`JobOperator` starts a :class:`core.job.Job` and polls it on a timer (``invoke``) or runs it
blocking (``execute``: scripts, background mode), then calls the operator's ``done`` on the main
thread. While it runs, :func:`status` shows the stage in the status bar and the panel, Esc (or
*Cancel*) stops it within a second, and :func:`running` tells the panels and polls that a job is
under way. :func:`cancel_all` (unregister) leaves no thread behind.
"""
from __future__ import annotations

import traceback

from ..core.errors import InputError
from ..core.job import Job

POLL_SECONDS = 0.1
#: window-manager flag set by *Cancel* (``tree_video.cancel``) and read by the running job's modal
CANCEL_FLAG = "tree_video_cancel"

_RUNNING: set = set()


class JobOperator:
    """Runs :meth:`make_job` in a worker thread driven by a modal timer (``invoke``), or blocking
    (``execute``: scripts, background mode), then :meth:`done` on the main thread.

    Mix it in before ``bpy.types.Operator``; set :attr:`what` to name the job in its messages."""

    _job: Job | None = None
    _timer = None
    what = "reconstruction"
    #: what a cancelled job leaves, for its message
    cancelled_note = "the scene is unchanged"

    def make_job(self, context) -> Job:
        raise NotImplementedError

    def done(self, context, result) -> set:
        raise NotImplementedError

    def execute(self, context):
        try:
            job = self.make_job(context)
        except InputError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        return self._finish(context, job.run_here())

    def invoke(self, context, event):
        try:
            self._job = self.make_job(context).start()
        except InputError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        _RUNNING.add(self._job)
        wm = context.window_manager
        self._timer = wm.event_timer_add(POLL_SECONDS, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        status(context, "starting", 0.0)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC" or cancel_requested(context):
            job.cancel()
            job.join(timeout=5.0)
            self._cleanup(context)
            self.report({"INFO"}, f"{self.what} cancelled; {self.cancelled_note}")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if isinstance(job, SteppedJob):
            job.tick()
        status(context, job.stage, job.fraction)
        context.window_manager.progress_update(int(100 * job.fraction))
        if not job.done:
            return {"RUNNING_MODAL"}
        self._cleanup(context)
        return self._finish(context, job)

    def _finish(self, context, job: Job):
        if job.cancelled:
            self.report({"INFO"}, f"{self.what} cancelled; {self.cancelled_note}")
            return {"CANCELLED"}
        if job.error:
            if job.details:
                print(job.details)
            self.report({"ERROR"}, job.error)
            return {"CANCELLED"}
        return self.done(context, job.result)

    def _cleanup(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        _RUNNING.discard(self._job)
        if CANCEL_FLAG in wm:
            del wm[CANCEL_FLAG]
        status(context, "", 0.0)


class SteppedJob:
    """Work that must run on the main thread (exporter operators), sliced into steps: ``steps`` is a
    generator that yields ``(stage, fraction)`` before each slice and returns the result.

    It has :class:`core.job.Job`'s surface (``stage``, ``fraction``, ``done``, ``result`` /
    ``error`` / ``cancelled``, ``cancel``, ``join``), so :class:`JobOperator` drives it: one slice
    per timer tick (``invoke``, Blender redraws in between) or all at once (``execute``).
    ``cancel()`` closes the generator (its ``finally`` clean-up runs) before the next slice."""

    def __init__(self, steps):
        self._steps = steps
        self.stage = "starting"
        self.fraction = 0.0
        self.result = None
        self.error: str | None = None
        self.details = ""
        self.cancelled = False
        self.done = False

    def start(self) -> "SteppedJob":
        return self

    def run_here(self) -> "SteppedJob":
        while not self.done:
            self.tick()
        return self

    def tick(self) -> None:
        """Run the next slice (returns at the generator's next ``yield``)."""
        if self.done:
            return
        try:
            self.stage, self.fraction = next(self._steps)
        except StopIteration as stop:
            self.result, self.done = stop.value, True
        except InputError as exc:
            self.error, self.done = str(exc), True
        except Exception as exc:  # internal error: keep the traceback for the report
            self.error = f"internal error ({exc.__class__.__name__}: {exc}); please report it"
            self.details, self.done = traceback.format_exc(), True

    def cancel(self) -> None:
        if not self.done:
            self._steps.close()
            self.cancelled = self.done = True

    def join(self, timeout: float | None = None) -> bool:
        return True


class Busy:
    """A main-thread phase of a job (a forest's trees built a few per tick after the worker grew
    them) held in the running jobs, so every other button stays greyed until it ends: put it in
    ``JobOperator._job`` and add it with :func:`hold`; ``_cleanup`` lets it go."""
    done = False


def hold(busy: Busy) -> Busy:
    """Count ``busy`` among the running jobs (see :class:`Busy`)."""
    _RUNNING.add(busy)
    return busy


def running() -> bool:
    """True while a job started by a :class:`JobOperator` is unfinished."""
    return any(not j.done for j in _RUNNING)


def request_cancel(context) -> None:
    """Ask the running job to stop (its modal sees it on the next event)."""
    context.window_manager[CANCEL_FLAG] = True


def cancel_requested(context) -> bool:
    return bool(context.window_manager.get(CANCEL_FLAG))


def status(context, stage: str, fraction: float) -> None:
    """Show ``stage`` and ``fraction`` (0..1) of the running job in the panel and the status bar
    (window manager ``tree_video_status`` / ``tree_video_progress``); ``""`` clears both."""
    wm = context.window_manager
    wm.tree_video_status = stage
    wm.tree_video_progress = 100.0 * fraction
    show_in_status_bar(context, bool(stage))
    redraw(context, "VIEW_3D")
    redraw(context, "CLIP_EDITOR")


def status_text(wm) -> str:
    """The running job in a few words, as the panel and the status bar show it: "Motion 72 %"."""
    stage = wm.tree_video_status
    return f"{stage[:1].upper()}{stage[1:]} {wm.tree_video_progress:.0f} %"


def draw_status_bar(header, context) -> None:
    """Drawn at the end of Blender's status bar (``STATUSBAR_HT_header``) while a job runs: its
    stage and progress bar, and a Cancel button."""
    wm = context.window_manager
    if not getattr(wm, "tree_video_status", ""):
        return
    row = header.layout.row(align=True)
    bar = row.row(align=True)
    bar.ui_units_x = 11
    if hasattr(bar, "progress"):                   # Blender 4.0+
        bar.progress(factor=wm.tree_video_progress / 100.0, type="BAR", text=status_text(wm))
    else:
        bar.label(text=status_text(wm), icon="TIME")
    row.operator("tree_video.cancel", text="", icon="CANCEL")


_STATUS_SHOWN: dict = {"text": None}


def status_bar_shown() -> bool:
    """True while :func:`draw_status_bar` is part of the status bar."""
    import bpy
    header = getattr(bpy.types, "STATUSBAR_HT_header", None)
    funcs = getattr(getattr(header, "draw", None), "_draw_funcs", None) or ()
    return any(f is draw_status_bar for f in funcs)


def show_in_status_bar(context, show: bool) -> None:
    """Add :func:`draw_status_bar` to the status bar (``show``) or take it out, and have the status
    bar redrawn when what it shows changes (Python cannot tag it directly: clearing the workspace's
    status text does, and a modal tool that set one sets it again on its next event)."""
    import bpy
    header = getattr(bpy.types, "STATUSBAR_HT_header", None)
    if header is None:
        return
    if show and not status_bar_shown():
        header.append(draw_status_bar)
    elif not show and status_bar_shown():
        header.remove(draw_status_bar)
    text = status_text(context.window_manager) if show and context is not None else None
    if text != _STATUS_SHOWN["text"]:
        _STATUS_SHOWN["text"] = text
        if context is None or bpy.app.background or getattr(context, "window", None) is None:
            return                                  # no status bar to redraw
        workspace = getattr(context, "workspace", None)
        if workspace is not None and hasattr(workspace, "status_text_set_internal"):
            workspace.status_text_set_internal(None)


def redraw(context, area_type: str) -> None:
    """Redraw every area of ``area_type`` in every window."""
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == area_type:
                area.tag_redraw()


def cancel_all(timeout: float = 2.0) -> None:
    """Stop every running job (unregister): no thread outlives the add-on."""
    for job in list(_RUNNING):
        job.cancel()
        job.join(timeout)
    _RUNNING.clear()
    show_in_status_bar(None, False)
