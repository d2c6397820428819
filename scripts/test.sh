#!/usr/bin/env bash
# The whole test suite: pytest on the bpy 5.0.1 wheel (Python 3.11, numpy 1.26); the add-on inside a
# real Blender 4.3 (tests, batch run, GUI screenshot) and on bpy 5.3 (Python 3.13, numpy 2.5); then
# the built extension installed into Blender 4.3 and its wheels into a clean Python 3.11 venv.
# pytest's exit 5 (no tests collected) counts as a failure.
set -uo pipefail
cd "$(dirname "$0")/.."
.venv/bin/python -m pytest -q -rs tests "$@"
rc=$?
if [ $rc -eq 5 ]; then echo "test: pytest collected no tests" >&2; exit 1; fi
[ $rc -eq 0 ] || exit $rc
bash scripts/test_blender.sh || exit 1
bash scripts/test_extension.sh
