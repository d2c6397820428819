"""A long core computation in a worker thread, with progress and cancel (no bpy: the Blender
operator polls it from a modal timer; tests and scripts can drive it directly)."""
from __future__ import annotations

import threading
import time
import traceback
from typing import Any, Callable

from .errors import Cancelled, InputError
from .progress import ProgressFn


class Job:
    """Runs ``work(progress)`` in a daemon thread.

    ``stage`` / ``fraction`` follow the progress callback; ``cancel()`` makes the next progress
    call raise :class:`Cancelled` inside the worker (stages report at least every few hundred ms).
    When ``done``: exactly one of ``result``, ``error`` (a one-line message for the user; the
    traceback of an internal error is in ``details``) or ``cancelled`` is set.
    """

    def __init__(self, work: Callable[[ProgressFn], Any], name: str = "tree_from_video-job"):
        self._work = work
        self._cancel = threading.Event()
        self._done = threading.Event()
        self.stage = "starting"
        self.fraction = 0.0
        self.result: Any = None
        self.error: str | None = None
        self.details: str = ""
        self.cancelled = False
        self.started = 0.0
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> "Job":
        self.started = time.monotonic()
        self._thread.start()
        return self

    def run_here(self) -> "Job":
        """Run the work in the calling thread (blocking callers: scripts, background mode)."""
        self.started = time.monotonic()
        self._run()
        return self

    def _progress(self, stage: str, fraction: float):
        self.stage, self.fraction = stage, fraction
        return not self._cancel.is_set()

    def _run(self) -> None:
        try:
            if self._cancel.is_set():
                raise Cancelled("cancelled before start")
            self.result = self._work(self._progress)
        except Cancelled:
            self.cancelled = True
        except InputError as exc:
            self.error = str(exc)
        except MemoryError:
            self.error = "out of memory: use a shorter frame range or a smaller scale"
        except Exception as exc:  # internal error: keep the traceback for the report
            self.error = f"internal error ({exc.__class__.__name__}: {exc}); please report it"
            self.details = traceback.format_exc()
        finally:
            self._done.set()

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def done(self) -> bool:
        return self._done.is_set()

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    def join(self, timeout: float | None = None) -> bool:
        """Wait for the worker; True if it has ended."""
        self._thread.join(timeout)
        return not self._thread.is_alive()
