"""Reading the small JSON files users hand us (outlines, species), with one clear error."""
from __future__ import annotations

import json
import os

from .errors import InputError


def read_json(path: str | os.PathLike, what: str, fix: str):
    """The parsed content of the JSON file ``path``; :class:`InputError` "``what`` is not readable
    JSON (reason); ``fix``" when it cannot be opened, decoded or parsed."""
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{what} is not readable JSON ({exc.__class__.__name__}); {fix}") from None
