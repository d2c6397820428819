"""Run part of the test suite inside a real Blender: ``blender -b --python tests/blender/run_in_blender.py``.

``-- tests/test_x.py [pytest args]`` runs only those. Exits Blender with pytest's exit code (5 — nothing collected — counts as failure).
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

import numpy

print(f"run_in_blender: Blender {bpy.app.version_string}, Python {sys.version.split()[0]}, numpy {numpy.__version__}",
      flush=True)
args = ["-q", "-p", "no:cacheprovider", "-o", "cache_dir=/tmp/tfv_pytest_cache",
        os.path.join(TESTS, "test_units.py"), os.path.join(TESTS, "test_register.py"), os.path.join(TESTS, "test_reconstruct_op.py"),
        os.path.join(TESTS, "test_sample_run.py"), os.path.join(TESTS, "test_scene.py"),
        os.path.join(TESTS, "test_exports.py"), os.path.join(TESTS, "test_annotation_outline.py"),
        os.path.join(TESTS, "test_twigs.py"), os.path.join(TESTS, "test_branch_mesh.py"),
        os.path.join(TESTS, "test_leaves_scene.py"), os.path.join(TESTS, "test_generate_op.py"),
        os.path.join(TESTS, "test_generate_batch.py")]
chosen = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []   # e.g. -- tests/test_x.py -s
if chosen:
    args = args[:5] + chosen
code = int(pytest.main(args))
if code == 5:
    code = 1
sys.exit(code)
