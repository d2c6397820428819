"""Running the web checks: Node scripts in web/ (the viewer in Debian's chromium through
puppeteer-core, the Khronos glTF validator). Both need ``make setup`` (apt chromium, ``npm ci`` in
web/); a missing piece fails with that fix, never skips."""
import json
import os
import shutil
import subprocess

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
WEB = os.path.join(ROOT, "web")


def _node() -> str:
    node = shutil.which("node")
    assert node, "node is not installed: run `make setup`"
    assert os.path.isdir(os.path.join(WEB, "node_modules", "three")), "web/node_modules missing: run `make setup`"
    return node


def validate_glb(*paths) -> list[dict]:
    """The Khronos validator's report per GLB: {file, errors, warnings, infos, messages}."""
    r = subprocess.run([_node(), os.path.join(WEB, "validate_gltf.mjs"), *map(str, paths)], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]


def render_viewer(out_dir, export_dir, size: int, ortho: tuple[float, float, float], shots: list[str]) -> dict:
    """Stills of web/viewer.html over ``export_dir`` (tree.glb, bone_anim.*): ``shots`` like
    "skin:0", "texture:12"; returns {renderer, files}."""
    assert shutil.which(os.environ.get("CHROMIUM", "chromium")) or os.path.exists("/usr/bin/chromium"), \
        "chromium is not installed: run `make setup`"
    r = subprocess.run([_node(), os.path.join(WEB, "check_viewer.mjs"), str(out_dir), str(export_dir), str(size),
                        ",".join(f"{v:.6f}" for v in ortho), *shots], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, (r.stdout[-1000:], r.stderr[-3000:])
    return json.loads(r.stdout.strip().splitlines()[-1])
