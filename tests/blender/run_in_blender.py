"""Run the tests marked ``blender`` inside a real Blender: ``blender -b --python tests/blender/run_in_blender.py``.

``-- tests/test_x.py [pytest args]`` runs those instead. Exits Blender with pytest's exit code (5 —
nothing collected — counts as failure).
"""
import os
import sys

import bpy  # noqa: F401  (we are inside Blender)

HERE = os.path.dirname(os.path.abspath(__file__))
TESTS = os.path.dirname(HERE)

try:
    import pytest
except ImportError:
    print("run_in_blender: this Blender's Python has no pytest", file=sys.stderr)
    sys.exit(1)

import numpy  # noqa: E402

print(f"run_in_blender: Blender {bpy.app.version_string}, Python {sys.version.split()[0]}, numpy {numpy.__version__}",
      flush=True)
# the tests marked ``blender`` (pyproject.toml), or those given after "--" (e.g. -- tests/test_x.py -s)
chosen = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
args = ["-q", "-p", "no:cacheprovider", "-o", "cache_dir=/tmp/tfv_pytest_cache"]
args += chosen or ["-m", "blender", TESTS]
code = int(pytest.main(args))
if code == 5:
    code = 1
sys.exit(code)
