#!/usr/bin/env bash
# The whole test suite: pytest on the bpy 5.0.1 wheel (Python 3.11, numpy 1.26); the add-on inside a
# real Blender 4.3 (tests, batch run, GUI screenshot) and on bpy 5.3 (Python 3.13, numpy 2.5); then
# the built extension installed into Blender 4.3 and its wheels into a clean Python 3.11 venv.
# pytest's exit 5 (no tests collected) counts as a failure. The wheel's tests run on every core (at
# most 4; pytest-xdist, one test file per worker at a time, so a file's fixtures are built once:
# 14 minutes on a 2-core machine, 28 one after the other), then those marked `alone` (they
# measure time) with nothing beside them.
set -uo pipefail
cd "$(dirname "$0")/.."
# pytest ARGS...: fails on a failure and on "no tests collected"
pytest() {
  .venv/bin/python -m pytest -q -rs "$@"
  local rc=$?
  if [ $rc -eq 5 ]; then echo "test: pytest collected no tests ($*)" >&2; exit 1; fi
  [ $rc -eq 0 ] || exit $rc
}
pytest -n auto --maxprocesses=4 --dist loadfile -m "not alone" tests "$@"
pytest -m alone tests "$@"
bash scripts/test_blender.sh || exit 1
bash scripts/test_extension.sh
