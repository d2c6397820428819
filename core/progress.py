"""Progress reporting and cancellation shared by every long stage.

A stage receives ``progress: ProgressFn | None``; it calls ``report(progress, stage, fraction)``
with ``fraction`` in [0, 1]. The callback may return ``False`` (or raise :class:`Cancelled`) to
cancel; :func:`report` turns a ``False`` into :class:`Cancelled` so every stage stops the same way.
"""
from __future__ import annotations

from typing import Callable, Optional

from .errors import Cancelled

ProgressFn = Callable[[str, float], Optional[bool]]


def report(progress: ProgressFn | None, stage: str, fraction: float) -> None:
    """Tell ``progress`` that ``stage`` is ``fraction`` (0..1) done; raise Cancelled if asked to stop."""
    if progress is None:
        return
    if progress(stage, float(min(max(fraction, 0.0), 1.0))) is False:
        raise Cancelled(f"cancelled during {stage}")


def sub_progress(progress: ProgressFn | None, start: float, end: float) -> ProgressFn | None:
    """A callback mapping a sub-stage's 0..1 onto ``start..end`` of the parent's scale."""
    if progress is None:
        return None

    def inner(stage: str, fraction: float):
        return progress(stage, start + (end - start) * fraction)

    return inner
