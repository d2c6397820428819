"""Batch entry (the logic is :mod:`cli`): ``python batch.py VIDEO --outline OUTLINE.json --out DIR``,
``python batch.py --generate N --species broad --out DIR``, or inside Blender
``blender -b --python batch.py -- VIDEO --outline ... --out DIR``; ``--help`` lists the options.
Exit codes: 0 success, 2 bad input (one line naming the problem and the fix), 1 internal error.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from package_loader import load_module  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    """Load the package and run :func:`cli.main` on ``argv``."""
    return load_module("cli").main(argv)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:] if "--" not in sys.argv else sys.argv[sys.argv.index("--") + 1:]))
