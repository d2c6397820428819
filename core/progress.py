"""Progress reporting and cancellation shared by every long stage.

A stage receives ``progress: ProgressFn | None``; it calls ``report(progress, stage, fraction)``
with ``fraction`` in [0, 1]. The callback may return ``False`` (or raise :class:`Cancelled`) to
cancel; :func:`report` turns a ``False`` into :class:`Cancelled` so every stage stops the same way.
"""
from __future__ import annotations

from typing import Callable, Mapping, Optional

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


def expected_seconds(costs: Mapping[str, tuple[float, float]], n_frames: int) -> dict[str, float]:
    """``{stage: seconds}`` from ``costs`` ``{stage: (fixed s, s per frame)}`` for a clip of
    ``n_frames`` frames (stages in their running order)."""
    n = max(int(n_frames), 1)
    return {stage: max(fixed + per_frame * n, 0.0) for stage, (fixed, per_frame) in costs.items()}


def stage_split(progress: ProgressFn | None, seconds: Mapping[str, float]) -> dict[str, ProgressFn | None]:
    """One callback per stage of ``seconds`` ``{stage: expected seconds}`` (in running order), each
    mapping its stage's 0..1 onto its share of the total time: the bar moves at an even pace when
    the estimates hold (stages that report their own 0..1 evenly)."""
    total = sum(seconds.values()) or 1.0
    out: dict[str, ProgressFn | None] = {}
    at = 0.0
    for stage, sec in seconds.items():
        out[stage] = sub_progress(progress, at / total, (at + sec) / total)
        at += sec
    return out
