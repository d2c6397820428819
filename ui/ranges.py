"""Panel properties' defaults and limits, read from the core's parameter dataclasses.

The core keeps each setting's default and range in its dataclass field (:mod:`core.params`). A
panel property made with :func:`ranged` takes its ``default``, ``min`` and ``max`` from there, so
the panel, the batch options and a script calling the core all start from the same tree. Not a
registered module: importing it needs no Blender.
"""
from __future__ import annotations

from typing import Any

from ..core.params import spec


def ranged(cls: type, name: str, *, open_min: float | None = None, **kw: Any) -> dict[str, Any]:
    """Keyword arguments for a ``bpy.props`` property that mirrors field ``name`` of the dataclass
    ``cls``: ``default`` and, for a numeric field, ``min`` = the core's lower bound and ``max`` =
    its upper bound (an unbounded side keeps Blender's limit). Where the core excludes the bound
    itself (e.g. a density > 0) ``open_min``, a small positive value above it, is the ``min``; it
    is required there and refused elsewhere. A field with choices gives only ``default`` (the
    panel lists the items, with their descriptions).

    ``kw`` is passed through: ``soft_min``/``soft_max`` for a narrower useful slider range inside
    the core's, ``name``, ``description``, ``subtype`` and so on."""
    s = spec(cls, name)
    where = f"{cls.__name__}.{name}"
    out: dict[str, Any] = {"default": s.default}
    if s.lo is not None and s.lo_open:
        if open_min is None or not open_min > s.lo or (s.hi is not None and open_min > s.hi):
            raise ValueError(f"{where} must be > {s.lo:g}: pass open_min, a small value inside {s.describe()}")
        out["min"] = open_min
    elif open_min is not None:
        raise ValueError(f"{where} has no open lower bound ({s.describe()}); drop open_min")
    elif s.lo is not None:
        out["min"] = s.lo
    if s.hi is not None:
        out["max"] = s.hi
    for key in ("soft_min", "soft_max"):
        if key in kw and not s.ok(kw[key]):
            raise ValueError(f"{where}: {key} {kw[key]} is outside the core's range {s.describe()}")
    out.update(kw)
    return out
