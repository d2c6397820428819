#!/usr/bin/env bash
# The add-on in real Blenders, via ../shared/tools/real-blender:
#  1. the Blender 4.3.2 binary (Python 3.13, numpy 2.2): tests/blender/run_in_blender.py runs the
#     unit, registration, sample, scene-building and export tests inside Blender (FBX and glTF; this
#     Debian build has no USD, so the USD test checks the clear "built without USD" error);
#  2. bpy 5.3.0 as a module (Python 3.13, numpy 2.5, OpenCV 5, usd-core) in a chroot venv: the same
#     tests plus the batch entry, USD export included.
set -euo pipefail
cd "$(dirname "$0")/.."
RB=../shared/tools/real-blender
if [ ! -x "$RB" ]; then
  echo "test_blender: $RB not found: the real-Blender tests need ../shared beside the repo" >&2
  exit 1
fi
"$RB" setup >/dev/null
echo "== Blender 4.3 (real binary)"
"$RB" run blender -b --factory-startup --python-exit-code 1 --python tests/blender/run_in_blender.py

VENV=/tmp/tree_from_video-bpy53
want=$(sha256sum requirements-bpy53.txt | cut -d' ' -f1)
if [ "$(cat "$VENV/.requirements.sha" 2>/dev/null)" != "$want" ]; then
  rm -rf "$VENV"
  "$RB" venv "$VENV" $(grep -v '^#' requirements-bpy53.txt) >/dev/null
  echo "$want" > "$VENV/.requirements.sha"
fi
echo "== bpy 5.3 (Python 3.13 module)"
"$RB" run "$VENV/bin/python" -m pytest -q -p no:cacheprovider \
  tests/test_units.py tests/test_register.py tests/test_sample_run.py tests/test_batch.py \
  tests/test_scene.py tests/test_exports.py
