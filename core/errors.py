"""Errors the user can act on.

Every stage raises :class:`InputError` for bad input (a missing video, a degenerate outline, ...)
with a one-line message that names the problem and the fix. Callers (the batch entry, operators)
show that message as it is; anything else is an internal error.
"""


class InputError(ValueError):
    """Bad input: the message names the problem and how to fix it (one line)."""


class Cancelled(Exception):
    """Raised by a progress callback's owner to stop a long stage cleanly."""
