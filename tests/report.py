"""Measurement tables collected while the tests run, printed once in pytest's terminal summary
(see ``pytest_terminal_summary`` in conftest.py): the 2D skeleton, lift, motion and silhouette
scores against ground truth. Tables are reports, not tests: the tests assert the bars."""
from __future__ import annotations

TABLES: dict[str, list[str]] = {}


def add(title: str, lines: list[str]) -> None:
    """Append ``lines`` to the table ``title`` (a header row first, when the table is new)."""
    TABLES.setdefault(title, []).extend(lines)
