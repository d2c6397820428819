#!/usr/bin/env bash
# Creates .venv (Python 3.11) with the pinned requirements and installs the system libraries the
# bpy wheel needs on a bare Debian (libegl1 included: without it a render aborts the process).
# Idempotent: a stamp file keyed on requirements.txt skips the work when nothing changed.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3
# ffmpeg: the 1080p H.264 and variable-frame-rate sample variants are encoded with its CLI
# chromium: the web viewer's checks (headless, WebGL through SwiftShader); nodejs/npm only where the
# machine has no node (the machines here have Node 20)
LIBS="libx11-6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libsm6 libxext6 libgl1 libegl1 ffmpeg chromium"
command -v node >/dev/null || LIBS="$LIBS nodejs npm"
missing=""
for p in $LIBS; do dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"; done
if [ -n "$missing" ]; then
  echo "setup: installing system libraries:$missing" >&2
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing >/dev/null
fi
stamp=.venv/.requirements.sha
want=$(sha256sum requirements.txt | cut -d' ' -f1)
if [ ! -x .venv/bin/python ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "setup: creating .venv with $($PY --version)" >&2
  "$PY" -m venv .venv
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -r requirements.txt
  echo "$want" > "$stamp"
fi
# web/: three.js for the viewer, puppeteer-core and the Khronos glTF validator for its checks
wstamp=web/node_modules/.lock.sha
wwant=$(sha256sum web/package-lock.json | cut -d' ' -f1)
if [ "$(cat "$wstamp" 2>/dev/null)" != "$wwant" ]; then
  echo "setup: npm ci in web/" >&2
  (cd web && npm ci --no-audit --no-fund --loglevel=error >/dev/null)
  echo "$wwant" > "$wstamp"
fi
