#!/usr/bin/env bash
# Runs tests/blender/run_in_blender.py inside the real Blender 4.3 binary (../shared/tools/real-blender).
set -euo pipefail
cd "$(dirname "$0")/.."
RB=../shared/tools/real-blender
if [ ! -x "$RB" ]; then
  echo "test_blender: $RB not found: the real-Blender test needs ../shared beside the repo" >&2
  exit 1
fi
"$RB" setup >/dev/null
"$RB" run blender -b --factory-startup --python-exit-code 1 --python tests/blender/run_in_blender.py
