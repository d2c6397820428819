#!/usr/bin/env bash
# The extension as users get it (`make test-extension`):
#  1. builds dist/tree_from_video-<version>-linux_x64.zip (scripts/build_extension.py --platform
#     linux-x64: scipy cp311 + cp313 and OpenCV wheels, ~130 MB downloaded once into wheels/);
#  2. installs it with `blender --command extension install-file -e` into the real Blender 4.3
#     (Python 3.13) with a clean user dir, checks the files and the wheels Blender extracted (the
#     cp313 ones), then in a background Blender with that user dir checks the add-on is enabled and
#     reconstructs sample_videos/broad (24 frames) through the installed package down to an
#     armature with bones and keys (scripts/extension_check.py), scipy and cv2 from the wheels;
#  3. the same through the cp313 wheels in the bpy 5.3 venv of scripts/test_blender.sh (Python 3.13,
#     numpy 2.5), when that venv exists;
#  4. the cp311 wheels of the zip installed into a fresh Python 3.11 venv with bpy 5.0.1 and
#     numpy 1.26.4 (what Blender 4.2-5.0 bundle), the add-on folder extracted from the zip, the
#     same reconstruction (bpy 5.0.1 is 374 MB: pip's cache makes this ~1 min).
# Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
RB=../shared/tools/real-blender
PY=.venv/bin/python
PY311=${PYTHON311:-python3.11}
SAMPLE=sample_videos/broad
[ -x "$RB" ] || { echo "test_extension: $RB not found: needs ../shared beside the repo" >&2; exit 1; }
[ -x "$PY" ] || { echo "test_extension: $PY missing: run make setup" >&2; exit 1; }
"$RB" setup >/dev/null

fail() { echo "test_extension: FAIL: $*" >&2; exit 1; }
t_start=$(date +%s)
lap() { local now; now=$(date +%s); echo "test_extension: $1 ($((now - t_lap)) s)"; t_lap=$now; }
t_lap=$t_start

WORK=$(mktemp -d /tmp/tfv-ext-test.XXXXXX)
trap 'rm -rf "$WORK"' EXIT

echo "== 1. build the linux-x64 zip"
"$PY" scripts/build_extension.py --platform linux-x64
VERSION=$("$PY" -c 'import tomllib; print(tomllib.load(open("blender_manifest.toml", "rb"))["version"])')
ZIP=dist/tree_from_video-$VERSION-linux_x64.zip
[ -s "$ZIP" ] || fail "$ZIP was not built"
lap "built $ZIP ($(du -m "$ZIP" | cut -f1) MB)"

echo "== 2. install into Blender 4.3 (clean user dir) and reconstruct through the installed add-on"
U=$WORK/user
"$RB" run -e BLENDER_USER_RESOURCES="$U" blender --factory-startup \
  --command extension install-file -r user_default -e "$ZIP" > "$WORK/install.log" 2>&1 \
  || { cat "$WORK/install.log"; fail "install-file exited non-zero"; }
cat "$WORK/install.log"
# install-file exits 0 even when it fails: check what it left behind.
EXT=$U/extensions/user_default/tree_from_video
for f in blender_manifest.toml __init__.py core/pipeline.py operators/scene/build.py ui/panel.py; do
  [ -f "$EXT/$f" ] || fail "install-file did not install $f (see the log above)"
done
SITE=$(echo "$U"/extensions/.local/lib/python3.*/site-packages)
[ -d "$SITE/scipy" ] && [ -d "$SITE/cv2" ] || fail "Blender did not extract the scipy/cv2 wheels into $SITE"
ls "$SITE" | grep -E '^(scipy|opencv).*dist-info$' | sed 's/^/  extracted: /'
ls "$SITE" | grep -q '^scipy-1\.17\.1\.dist-info$' || fail "Blender 4.3 (Python 3.13) should have picked the cp313 scipy 1.17.1"
"$RB" run -e BLENDER_USER_RESOURCES="$U" blender -b --python-exit-code 1 --python scripts/extension_check.py -- \
  --module bl_ext.user_default.tree_from_video --sample "$SAMPLE" --site "$SITE" \
  || fail "the installed extension did not reconstruct the sample in Blender 4.3"
lap "Blender 4.3: installed, enabled, reconstructed"

echo "== 3. the cp313 wheels with bpy 5.3 (Python 3.13, numpy 2.5)"
V53=/tmp/tree_from_video-bpy53
if [ -x "$V53/bin/python" ]; then
  "$RB" run -e PYTHONPATH="$SITE" "$V53/bin/python" scripts/extension_check.py \
    --package-dir "$EXT" --sample "$SAMPLE" --site "$SITE" \
    || fail "the cp313 wheels did not work with bpy 5.3"
  lap "bpy 5.3: reconstructed through the cp313 wheels"
else
  echo "test_extension: skipped: $V53 not built (make test-blender builds it)"
fi

echo "== 4. the cp311 wheels in a clean Python 3.11 venv with bpy 5.0.1 + numpy 1.26.4"
command -v "$PY311" >/dev/null || fail "$PY311 not found (set PYTHON311)"
PKG=$WORK/pkg/tree_from_video
mkdir -p "$PKG"
"$PY" -c 'import sys, zipfile; zipfile.ZipFile(sys.argv[1]).extractall(sys.argv[2])' "$ZIP" "$PKG"
mapfile -t WHEELS < <(ls "$PKG"/wheels/*.whl | grep -E 'cp311|abi3')
[ ${#WHEELS[@]} -eq 2 ] || fail "expected a cp311 scipy and an abi3 OpenCV wheel in the zip, got: ${WHEELS[*]}"
"$PY311" -m venv "$WORK/venv"
VPY=$WORK/venv/bin/python
quiet() { sed '/is ignored: it is neither a file nor a directory/d'; }   # this machine's pip.conf
"$VPY" -m pip install -q --disable-pip-version-check bpy==5.0.1 numpy==1.26.4 2>&1 | quiet
"$VPY" -m pip install -q --disable-pip-version-check --no-index "${WHEELS[@]}" 2>&1 | quiet
lap "venv: bpy 5.0.1, numpy 1.26.4, $(basename -a "${WHEELS[@]}" | tr '\n' ' ')"
VSITE=$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
"$VPY" scripts/extension_check.py --package-dir "$PKG" --sample "$SAMPLE" --site "$VSITE" \
  || fail "the cp311 wheels did not work with bpy 5.0.1 / numpy 1.26"
lap "bpy 5.0.1: reconstructed through the cp311 wheels"

echo "test_extension: all passed in $(( $(date +%s) - t_start )) s"
