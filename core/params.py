"""The product's defaults and ranges, in one place: fields of the core's parameter dataclasses.

A field made with :func:`param` carries its range (and, for strings, its choices) in the
dataclass field's metadata. The stage checks (:func:`check`), the Blender panel's properties
(:func:`spec` → ``default``/``min``/``max``) and the batch options (:func:`spec` → ``default`` and
the help text) all read them from here, so a script that calls the core gets the tree the add-on
and the CLI make.
"""
from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from typing import Any

from .errors import InputError


@dataclass(frozen=True)
class Spec:
    """A parameter's default and what it may be: ``lo``..``hi`` (None: unbounded; ``lo_open``: the
    bound itself is excluded) or one of ``choices``; ``what`` names it in an error, ``fix`` is
    the hint appended to one; ``unit`` the unit it is in (for help texts)."""

    default: Any
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: tuple[str, ...] = ()
    what: str = ""
    unit: str = ""
    fix: str = ""
    pattern: str = ""               # a string also accepted besides ``choices`` (a regular expression)
    also: str = ""                  # how a user writes such a string ("#RRGGBB")

    def describe(self) -> str:
        """The range as a user reads it: ``2..9``, ``(0, 1]``, ``>= 0``, ``one of a, b``."""
        if self.choices:
            return "one of " + ", ".join(self.choices + ((self.also,) if self.also else ()))
        if self.lo is not None and self.hi is not None:
            return f"({self.lo:g}, {self.hi:g}]" if self.lo_open else f"{self.lo:g}..{self.hi:g}"
        if self.lo is not None:
            return f"> {self.lo:g}" if self.lo_open else f">= {self.lo:g}"
        if self.hi is not None:
            return f"<= {self.hi:g}"
        return "any value"

    def ok(self, value: Any) -> bool:
        if self.choices:
            return value in self.choices or bool(self.pattern and isinstance(value, str)
                                                 and re.fullmatch(self.pattern, value))
        if value is None or isinstance(value, bool):
            return True
        v = float(value)
        if not math.isfinite(v):
            return False
        if self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo):
            return False
        return not (self.hi is not None and v > self.hi)


def param(default: Any, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
          choices: tuple[str, ...] = (), what: str = "", unit: str = "", fix: str = "",
          pattern: str = "", also: str = "") -> Any:
    """A dataclass field with ``default`` and its :class:`Spec` in the metadata."""
    s = Spec(default, lo, hi, lo_open, tuple(choices), what, unit, fix, pattern, also)
    return dataclasses.field(default=default, metadata={"spec": s})


def spec(cls: type, name: str) -> Spec:
    """The :class:`Spec` of field ``name`` of the dataclass ``cls``."""
    for f in dataclasses.fields(cls):
        if f.name == name:
            s = f.metadata.get("spec")
            if s is None:
                raise KeyError(f"{cls.__name__}.{name} has no range")
            return s
    raise KeyError(f"{cls.__name__} has no field {name}")


def specs(cls: type) -> dict[str, Spec]:
    """Every ranged field of ``cls``: ``{name: Spec}``."""
    return {f.name: f.metadata["spec"] for f in dataclasses.fields(cls) if "spec" in f.metadata}


def check(obj: Any) -> None:
    """Raise :class:`InputError` for the first ranged field of the dataclass ``obj`` that is out
    of range: "<what> <value> out of range; use <range>[ (<fix>)]", or "unknown <what> '<value>';
    choose one of <choices>"."""
    for name, s in specs(type(obj)).items():
        value = getattr(obj, name)
        if not s.ok(value) and s.choices:
            raise InputError(f"unknown {s.what or name} '{value}'; choose {s.describe()}")
        if not s.ok(value):
            hint = f" ({s.fix})" if s.fix else ""
            raise InputError(f"{s.what or name} {value} out of range; use {s.describe()}{hint}")


def same_as(cls: type, name: str) -> Any:
    """A field with the default and range of ``cls.name`` (one setting seen by two dataclasses)."""
    s = spec(cls, name)
    return dataclasses.field(default=s.default, metadata={"spec": s})
