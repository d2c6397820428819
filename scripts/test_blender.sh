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

echo "== Blender 4.3: blender -b --python batch.py -- ..."
OUT=$(mktemp -d /tmp/tfv-batch.XXXXXX)
trap 'rm -rf "$OUT"' EXIT
"$RB" run blender -b --factory-startup --python-exit-code 1 --python batch.py -- \
  sample_videos/broad/video.mp4 --outline sample_videos/broad/outline.json --out "$OUT/run" \
  --npz --fbx --gltf --blend --preview --frames 0:48 --no-video --quiet > "$OUT/log" 2>&1 \
  || { tail -20 "$OUT/log"; echo "batch under Blender 4.3 failed" >&2; exit 1; }
for f in skeleton.npz tree3d.npz result.npz overlay.png preview.png tree.fbx tree.glb tree.blend; do
  [ -s "$OUT/run/$f" ] || { echo "batch under Blender 4.3 did not write $f" >&2; exit 1; }
done
set +e
"$RB" run blender -b --factory-startup --python-exit-code 1 --python batch.py -- \
  sample_videos/broad/video.mp4 --outline sample_videos/broad/outline.json --out "$OUT/usd" --usd > "$OUT/log" 2>&1
rc=$?
set -e
if [ $rc -ne 2 ] || ! grep -q "without USD" "$OUT/log" || [ -e "$OUT/usd" ]; then
  tail -5 "$OUT/log"; echo "--usd in a Blender without USD should exit 2 with a clear error (got $rc)" >&2; exit 1
fi
echo "batch under Blender 4.3: all files written; --usd refused clearly"

echo "== Blender 4.3 GUI: screenshot of the panel after a reconstruction"
"$RB" gui-shot "$OUT/panel.png" --size 1600x900 --wait 10 -- \
  blender --factory-startup --python tests/gui/panel_shot.py > "$OUT/gui.log" 2>&1 \
  || { tail -20 "$OUT/gui.log"; echo "panel screenshot failed or blank" >&2; exit 1; }
grep -q "reconstruct: {'FINISHED'}" "$OUT/gui.log" || { tail -20 "$OUT/gui.log"; echo "no reconstruction in the GUI run" >&2; exit 1; }
grep -q "ui ready" "$OUT/gui.log" || { echo "the sidebar never opened on the Tree tab" >&2; exit 1; }
echo "panel screenshot: $(stat -c %s "$OUT/panel.png") bytes"

echo "== Blender 4.3 GUI: a generated forest and the Generate sub-panel"
"$RB" gui-shot "$OUT/generate.png" --size 1600x1000 --wait 10 -- \
  blender --factory-startup --python tests/gui/generate_shot.py > "$OUT/generate.log" 2>&1 \
  || { tail -20 "$OUT/generate.log"; echo "generate screenshot failed or blank" >&2; exit 1; }
grep -q "forest: {'FINISHED'}" "$OUT/generate.log" || { tail -20 "$OUT/generate.log"; echo "no forest in the GUI run" >&2; exit 1; }
grep -q "ui ready" "$OUT/generate.log" || { echo "the sidebar never opened on the Tree tab" >&2; exit 1; }
echo "generate screenshot: $(stat -c %s "$OUT/generate.png") bytes"

echo "== Blender 4.3 GUI: Track & Preview drawn over the clip in the Movie Clip editor"
"$RB" gui-shot "$OUT/clip.png" --size 1600x900 --wait 10 -- \
  blender --factory-startup --python tests/gui/clip_shot.py > "$OUT/clip.log" 2>&1 \
  || { tail -20 "$OUT/clip.log"; echo "clip editor screenshot failed or blank" >&2; exit 1; }
grep -q "preview: {'FINISHED'}" "$OUT/clip.log" && grep -q "clip ready" "$OUT/clip.log" \
  || { tail -20 "$OUT/clip.log"; echo "the preview did not run in the GUI" >&2; exit 1; }
echo "clip overlay screenshot: $(stat -c %s "$OUT/clip.png") bytes"

echo "== Blender 4.3 GUI: outline from an annotation drawn over the clip, then Track & Preview"
"$RB" gui-shot "$OUT/annotation.png" --size 1600x900 --wait 12 -- \
  blender --factory-startup --python tests/gui/annotation_shot.py > "$OUT/annotation.log" 2>&1 \
  || { tail -20 "$OUT/annotation.log"; echo "annotation screenshot failed or blank" >&2; exit 1; }
grep -q "status after drawing: (True" "$OUT/annotation.log" && grep -q "preview: {'FINISHED'}" "$OUT/annotation.log" \
  || { tail -20 "$OUT/annotation.log"; echo "the annotation outline did not work in the GUI" >&2; exit 1; }

echo "== Blender 4.3 GUI: Reconstruct as a user starts it (INVOKE, modal), then cancelled"
"$RB" gui-shot "$OUT/modal.png" --size 1200x800 --wait 25 -- \
  blender --factory-startup --python tests/gui/modal_run.py > "$OUT/modal.log" 2>&1 || true
grep -E "invoke returned|stages seen|finished" "$OUT/modal.log" || true
grep -q "invoke returned {'RUNNING_MODAL'}" "$OUT/modal.log" \
  && grep -q "finished: collection present with 3 objects" "$OUT/modal.log" \
  || { tail -20 "$OUT/modal.log"; echo "the modal Reconstruct did not finish with the tree" >&2; exit 1; }
"$RB" gui-shot "$OUT/cancel.png" --size 1200x800 --wait 15 -- \
  blender --factory-startup --python tests/gui/modal_run.py -- --cancel > "$OUT/cancel.log" 2>&1 || true
grep -E "cancel requested|after cancel" "$OUT/cancel.log" || true
grep -q "after cancel: collection absent, objects 3" "$OUT/cancel.log" \
  || { tail -20 "$OUT/cancel.log"; echo "cancelling the modal Reconstruct left something behind" >&2; exit 1; }

VENV=/tmp/tree_from_video-bpy53
want=$(sha256sum requirements-bpy53.txt | cut -d' ' -f1)
if [ "$(cat "$VENV/.requirements.sha" 2>/dev/null)" != "$want" ]; then
  rm -rf "$VENV"
  "$RB" venv "$VENV" $(grep -v '^#' requirements-bpy53.txt) >/dev/null
  echo "$want" > "$VENV/.requirements.sha"
fi
echo "== bpy 5.3 (Python 3.13 module)"
"$RB" run "$VENV/bin/python" -m pytest -q -p no:cacheprovider \
  tests/test_units.py tests/test_register.py tests/test_reconstruct_op.py tests/test_sample_run.py tests/test_batch.py tests/test_batch_3d.py \
  tests/test_scene.py tests/test_exports.py tests/test_annotation_outline.py tests/test_leaves_scene.py tests/test_twigs.py tests/test_branch_mesh.py \
  tests/test_generate_op.py tests/test_generate_batch.py tests/test_pgm.py tests/test_growth.py tests/test_forest.py
