"""The web viewer as an output (issue 33, ``--viewer``): ``viewer.html`` beside the exports, which
plays ``tree.glb`` skinned and, when ``bone_anim.exr`` is there, from the bone texture (key *m*),
with three.js copied into ``viewer/`` (an import map points ``three`` and ``three/addons/`` there:
no CDN, nothing fetched from the network). Browsers refuse ES modules from ``file://``, so the page
is opened through a local server, e.g. ``python -m http.server`` in the folder.

The page and its script are the repository's ``web/viewer.html`` and ``web/viewer.js``; three.js
comes from ``web/node_modules`` (``make setup`` installs it with npm; the pinned version is in
``web/package.json``).
"""
from __future__ import annotations

import os
import shutil

from ..errors import InputError
from ..fileio import atomic_write_bytes

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WEB = os.path.join(ROOT, "web")
THREE = os.path.join(WEB, "node_modules", "three")
#: three.js files the viewer imports (build, and the addons its loaders import), relative to the package
THREE_FILES = ("LICENSE", "build/three.module.js", "build/three.core.js",
               "examples/jsm/loaders/GLTFLoader.js", "examples/jsm/loaders/EXRLoader.js",
               "examples/jsm/utils/BufferGeometryUtils.js", "examples/jsm/utils/SkeletonUtils.js",
               "examples/jsm/libs/fflate.module.js")
FILES = ("viewer.html", "viewer")
IMPORT_MAP = ('{ "imports": { "three": "./viewer/three/build/three.module.js",\n'
              '               "three/addons/": "./viewer/three/examples/jsm/" } }')


def check_viewer_sources() -> None:
    """Raise :class:`InputError` naming the fix when three.js is not installed."""
    missing = [f for f in THREE_FILES if not os.path.isfile(os.path.join(THREE, f))]
    if missing:
        raise InputError(f"--viewer needs three.js in {os.path.join(WEB, 'node_modules')} (missing {missing[0]}); "
                         "run `make setup` (or `npm ci` in web/) first")


def write_viewer(folder: str | os.PathLike) -> str:
    """``viewer.html`` and ``viewer/`` (its script and three.js) in ``folder``; returns the page's
    path. ``viewer/`` is replaced whole (it holds only what this writes)."""
    check_viewer_sources()
    folder = os.fspath(folder)
    page = open(os.path.join(WEB, "viewer.html"), encoding="utf-8").read()
    start = page.index('<script type="importmap">') + len('<script type="importmap">')
    end = page.index("</script>", start)
    page = page[:start] + "\n" + IMPORT_MAP + "\n" + page[end:]
    page = page.replace('src="./viewer.js"', 'src="./viewer/viewer.js"')
    lib = os.path.join(folder, "viewer")
    tmp = os.path.join(folder, ".viewer.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        os.makedirs(os.path.join(tmp, "three"))
        shutil.copy2(os.path.join(WEB, "viewer.js"), os.path.join(tmp, "viewer.js"))
        for f in THREE_FILES:
            dst = os.path.join(tmp, "three", f)
            os.makedirs(os.path.dirname(dst), exist_ok=True)
            shutil.copy2(os.path.join(THREE, f), dst)
        shutil.rmtree(lib, ignore_errors=True)
        os.replace(tmp, lib)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    path = os.path.join(folder, FILES[0])
    atomic_write_bytes(path, page.encode())
    return path
