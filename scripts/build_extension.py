"""Build the Tree from Video extension zips, one per platform, with scipy and OpenCV as wheels.

    .venv/bin/python scripts/build_extension.py                        # every platform, both Pythons
    .venv/bin/python scripts/build_extension.py --platform linux-x64   # CI / testing: one platform
    .venv/bin/python scripts/build_extension.py --download-only        # fill wheels/, build nothing

Blender bundles numpy but not scipy or OpenCV, so the extension ships them as wheels (the core
imports nothing else: numpy, scipy, cv2). Two Pythons are covered:

* cp311: Blender 4.2-5.0 (numpy 1.26 bundled) - scipy 1.13.1, the tested dev-venv version;
* cp313: Blender 5.1+ (numpy 2.x bundled) - scipy 1.17.1, the newest scipy whose numpy range
  (>=1.26.4,<2.7) covers every numpy those Blenders declare (bpy 5.1.0: numpy<2; 5.1.1-5.3: >=2.2).

OpenCV is one wheel per platform for both Pythons: its wheels are ``cp37-abi3``, which Blender
4.3+ treats as compatible with *every* Python >= 3.7, and of two wheels of one package Blender
installs the newer. A newer OpenCV for cp313 (4.12+ needs numpy 2) would therefore also be the
one installed on Python 3.11 / numpy 1.26 and break Blender 4.2-5.0. 4.11.0.86 works with numpy
1.26 and 2.x. :func:`check_selection` replays Blender's wheel choice and fails the build if any
(Python, platform) pair would get another set than intended.

Steps: ``pip download --only-binary=:all: --no-deps --python-version X --platform TAG`` into
``wheels/`` (cached, gitignored), for each platform trying the oldest platform tag first (the
widest OS support); then a staging copy of the repository in a temporary folder gets a manifest
with ``wheels``/``platforms`` filled in (the committed ``blender_manifest.toml`` keeps
``wheels = []`` and is never written), ``blender --command extension validate`` checks it and
``extension build --split-platforms`` writes ``dist/tree_from_video-<version>-<platform>.zip``,
each validated again and checked for its contents. Blender is the real Blender of
``../shared/tools/real-blender`` when present, else ``blender`` on PATH (``--blender`` overrides).
"""
from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
import zipfile
from dataclasses import dataclass

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MANIFEST = "blender_manifest.toml"
REAL_BLENDER = os.path.join(os.path.dirname(ROOT), "shared", "tools", "real-blender")

#: Python version -> (what uses it, {distribution: version}).
PYTHONS = {
    "3.11": ("Blender 4.2-5.0, numpy 1.26", {"scipy": "1.13.1"}),
    "3.13": ("Blender 5.1+, numpy 2.x", {"scipy": "1.17.1"}),
}
#: abi3 wheels: one version for every Python (see the module docstring).
SHARED = {"opencv-contrib-python-headless": "4.11.0.86"}
#: The newest Python of each range, for a build that leaves the other range out.
PYTHON_BLENDER_RANGE = {"3.11": ("4.2.0", "5.1.0"), "3.13": ("5.1.0", None)}

#: Blender platform -> (wheel arch suffix, pip platform tags, oldest OS first).
PLATFORMS = {
    "linux-x64": ("x86_64", ["manylinux2014_x86_64", "manylinux_2_28_x86_64"]),
    "windows-x64": ("amd64", ["win_amd64"]),
    "macos-arm64": ("arm64", [f"macosx_{v}_0_arm64" for v in (11, 12, 13, 14, 15)]),
    "macos-x64": ("x86_64", ["macosx_10_13_x86_64"] + [f"macosx_{v}_0_x86_64" for v in (11, 12, 13, 14, 15)]),
}
PLATFORM_PREFIX = {"linux": "manylinux", "windows": "win", "macos": "macosx"}

#: What a built zip must hold, and must not.
REQUIRED = ("__init__.py", MANIFEST, "core/pipeline.py", "operators/__init__.py", "operators/scene/__init__.py",
            "operators/scene/build.py", "ui/__init__.py")
FORBIDDEN = re.compile(r"^(tests|benchmarks|scripts|sample_videos|docs|out|dist|\.git|\.ci|\.venv)/"
                       r"|\.(mp4|npz|pyc)$|__pycache__/")


@dataclass(frozen=True)
class Wheel:
    path: str

    @property
    def filename(self) -> str:
        return os.path.basename(self.path)

    def _parts(self) -> list[str]:
        return self.filename[:-4].split("-")

    @property
    def name(self) -> str:
        return norm(self._parts()[0])

    @property
    def version(self) -> str:
        return self._parts()[1]

    @property
    def python_tag(self) -> str:
        return self._parts()[-3]

    @property
    def abi_tag(self) -> str:
        return self._parts()[-2]

    @property
    def platform_tags(self) -> list[str]:
        return self._parts()[-1].split(".")

    def fits_platform(self, platform: str) -> bool:
        """Blender's rule: OS prefix and architecture suffix (glibc/macOS versions ignored)."""
        os_name = platform.split("-")[0]
        arch = PLATFORMS[platform][0]
        return any(t == "any" or (t.startswith(PLATFORM_PREFIX[os_name])
                                  and (t.endswith("_" + arch) or t == arch
                                       or (os_name == "macos" and t.endswith("_universal2"))))
                   for t in self.platform_tags)

    def fits_python(self, python: str) -> bool:
        """Blender 4.3+'s rule: the exact CPython, or a stable-ABI (abi3) wheel for an older one."""
        want = tuple(int(x) for x in python.split("."))
        for tag in self.python_tag.split("."):
            m = re.fullmatch(r"(?:cp|py)(\d)(\d*)", tag)
            if not m:
                continue
            have = (int(m.group(1)), int(m.group(2))) if m.group(2) else (int(m.group(1)),)
            if have == want or have == want[:1]:
                return True
            if self.abi_tag == "abi3" and len(have) == 2 and have[0] == want[0] and want >= have:
                return True
        return False


def norm(name: str) -> str:
    return re.sub(r"[-_.]+", "_", name).lower()


def log(msg: str) -> None:
    print(f"build_extension: {msg}", file=sys.stderr, flush=True)


def mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


# -- wheels ------------------------------------------------------------------------------------

def wanted(pythons: list[str]) -> list[tuple[str, str, str]]:
    """(distribution, version, python used for the download) for the selected Pythons."""
    out = [(d, v, py) for py in pythons for d, v in PYTHONS[py][1].items()]
    out += [(d, v, pythons[0]) for d, v in SHARED.items()]
    return out


def find_cached(wheels_dir: str, dist: str, version: str, python: str, platform: str) -> Wheel | None:
    if not os.path.isdir(wheels_dir):
        return None
    for f in sorted(os.listdir(wheels_dir)):
        if not f.endswith(".whl"):
            continue
        w = Wheel(os.path.join(wheels_dir, f))
        if w.name == norm(dist) and w.version == version and w.fits_python(python) and w.fits_platform(platform):
            return w
    return None


def download(wheels_dir: str, dist: str, version: str, python: str, platform: str) -> Wheel:
    """The wheel from ``wheels/`` if there, else ``pip download`` trying the oldest OS tag first."""
    if (w := find_cached(wheels_dir, dist, version, python, platform)) is not None:
        return w
    os.makedirs(wheels_dir, exist_ok=True)
    tried = []
    for tag in PLATFORMS[platform][1]:
        cmd = [sys.executable, "-m", "pip", "download", "--only-binary=:all:", "--no-deps",
               "--disable-pip-version-check", "--python-version", python, "--platform", tag,
               "--dest", wheels_dir, f"{dist}=={version}"]
        r = subprocess.run(cmd, capture_output=True, text=True)
        tried.append(tag)
        if r.returncode == 0 and (w := find_cached(wheels_dir, dist, version, python, platform)):
            log(f"downloaded {w.filename} ({mb(os.path.getsize(w.path))})")
            return w
        if r.returncode != 0 and not re.search(r"No matching distribution|Could not find a version", r.stderr):
            sys.exit(f"build_extension: pip download failed for {dist}=={version} ({tag}):\n{r.stderr[-2000:]}")
    sys.exit(f"build_extension: no {dist}=={version} wheel for Python {python} on {platform} "
             f"(tried {', '.join(tried)}); pick another version in scripts/build_extension.py")


def blender_selects(wheels: list[Wheel], python: str, platform: str) -> dict[str, Wheel]:
    """What Blender 4.3+ installs: wheels that fit the platform and Python, newest per package."""
    return _newest([w for w in wheels if w.fits_platform(platform) and w.fits_python(python)])


def _newest(wheels: list[Wheel]) -> dict[str, Wheel]:
    """Blender's de-duplication: per package the highest version (ties: the greater file name)."""
    chosen: dict[str, Wheel] = {}
    for w in wheels:
        old = chosen.get(w.name)
        if old is None or (_vkey(old.version), old.filename) < (_vkey(w.version), w.filename):
            chosen[w.name] = w
    return chosen


def _vkey(v: str) -> tuple:
    parts = (re.match(r"(\d*)(.*)", p) for p in re.split(r"[.+-]", v))
    return tuple((int(m.group(1)) if m.group(1) else -1, m.group(2)) for m in parts)


def check_selection(wheels: list[Wheel], pythons: list[str], platforms: list[str]) -> None:
    """Fail unless Blender would install exactly the intended wheel of every package."""
    bad = []
    for platform in platforms:
        for py in pythons:
            want = {norm(d): v for d, v in {**PYTHONS[py][1], **SHARED}.items()}
            got = {n: w.version for n, w in blender_selects(wheels, py, platform).items()}
            if got != want:
                bad.append(f"{platform} Python {py}: Blender would install {got}, intended {want}")
    if bad:
        sys.exit("build_extension: wheel set is inconsistent:\n  " + "\n  ".join(bad))
    if len(pythons) > 1:
        # Blender 4.2.0 does not filter wheels by Python (added after 4.2.0, ref #128750): it
        # installs every wheel of the platform and keeps the newest version of each package.
        for platform in platforms:
            got = _newest([w for w in wheels if w.fits_platform(platform)])
            wrong = [w.filename for w in got.values() if not w.fits_python(pythons[0])]
            if wrong:
                log(f"warning: a Blender that ignores wheel Python tags (4.2.0) would install "
                    f"{', '.join(wrong)} on {platform} (likewise on the other platforms) and fail to "
                    f"import it; zips for such a Blender: --python {pythons[0]}")
                break


# -- manifest ----------------------------------------------------------------------------------

def toml_list(key: str, items: list[str]) -> str:
    if not items:
        return f"{key} = []"
    return f"{key} = [\n" + "".join(f'  "{i}",\n' for i in items) + "]"


def filled_manifest(text: str, wheels: list[str], platforms: list[str], pythons: list[str]) -> str:
    """The committed manifest with ``wheels`` and ``platforms`` (and, for a build that covers one
    Python only, the Blender range of that Python) filled in."""
    top, sep, rest = text.partition("\n[")          # top-level keys come before the first table
    if not re.search(r"(?m)^wheels\s*=", top):
        sys.exit(f"build_extension: {MANIFEST} has no top-level 'wheels = [...]' to fill")
    top = re.sub(r"(?ms)^wheels\s*=\s*\[.*?\]", lambda _: toml_list("wheels", wheels), top, count=1)
    if re.search(r"(?m)^platforms\s*=", top):
        top = re.sub(r"(?ms)^platforms\s*=\s*\[.*?\]", lambda _: toml_list("platforms", platforms), top, count=1)
    else:
        top = re.sub(r"(?ms)^(wheels\s*=\s*\[.*?\])", lambda m: m.group(1) + "\n" + toml_list("platforms", platforms),
                     top, count=1)
    if len(pythons) == 1:
        lo, hi = PYTHON_BLENDER_RANGE[pythons[0]]
        if lo != "4.2.0":
            top = re.sub(r'(?m)^blender_version_min\s*=.*$', f'blender_version_min = "{lo}"', top)
        if hi is not None:
            top = re.sub(r'(?m)^blender_version_max\s*=.*\n', "", top)
            top = re.sub(r'(?m)^(blender_version_min\s*=.*)$', lambda m: m.group(1) + f'\nblender_version_max = "{hi}"',
                         top, count=1)
    out = top + sep + rest
    data = tomllib.loads(out)                       # must still parse, with the lists we meant
    assert data["wheels"] == wheels and data["platforms"] == platforms, "manifest rewrite went wrong"
    return out


# -- Blender -----------------------------------------------------------------------------------

def blender_cmd(arg: str | None) -> list[str]:
    if arg:
        return shlex.split(arg)
    if env := os.environ.get("BLENDER"):
        return shlex.split(env)
    if os.access(REAL_BLENDER, os.X_OK):
        return [REAL_BLENDER, "run", "blender"]
    return ["blender"]


def run_blender(blender: list[str], *args: str) -> str:
    r = subprocess.run(blender + ["--command", "extension", *args], cwd=ROOT, capture_output=True, text=True)
    out = (r.stdout + r.stderr).strip()
    if r.returncode != 0 or "FATAL_ERROR" in out:
        sys.exit(f"build_extension: blender --command extension {' '.join(args)} failed ({r.returncode}):\n{out}")
    return out


def stage_tree(stage: str) -> None:
    """Copy the working tree (what a `--source-dir .` build would see) minus the bulky bits."""
    skip = {".git", ".venv", "out", "dist", "wheels", "__pycache__", ".pytest_cache", "node_modules"}
    shutil.copytree(ROOT, stage, ignore=lambda d, names: [n for n in names if n in skip or n.endswith(".pyc")],
                    symlinks=True)


def link_or_copy(src: str, dst: str) -> None:
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def check_zip(path: str, platform: str, expected_wheels: list[str]) -> tuple[int, list[tuple[str, int]]]:
    with zipfile.ZipFile(path) as z:
        infos = z.infolist()
        names = [i.filename for i in infos]
        manifest = tomllib.loads(z.read(MANIFEST).decode())
    problems = [f"missing {r}" for r in REQUIRED if r not in names]
    problems += [f"should not ship {n}" for n in names if FORBIDDEN.search(n)]
    zwheels = sorted(n for n in names if n.endswith(".whl"))
    want = sorted(w.lstrip("./") for w in expected_wheels)
    if zwheels != want:
        problems.append(f"wheels {zwheels} != expected {want}")
    gen = manifest.get("build", {}).get("generated", {})
    if gen.get("platforms") != [platform]:
        problems.append(f"generated platforms {gen.get('platforms')} != [{platform!r}]")
    if problems:
        sys.exit(f"build_extension: {os.path.basename(path)}:\n  " + "\n  ".join(problems))
    return os.path.getsize(path), [(i.filename, i.compress_size) for i in infos]


# -- main --------------------------------------------------------------------------------------

def csv(values: list[str] | None, allowed, what: str) -> list[str]:
    out = []
    for v in values or []:
        out += [x.strip() for x in v.split(",") if x.strip()]
    for x in out:
        if x not in allowed:
            sys.exit(f"build_extension: unknown {what} '{x}'; choose from {', '.join(allowed)}")
    return list(dict.fromkeys(out)) or list(allowed)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--platform", action="append", metavar="P",
                    help=f"limit to these Blender platforms (repeat or comma-separate): {', '.join(PLATFORMS)}")
    ap.add_argument("--python", action="append", metavar="V",
                    help=f"limit to these Pythons: {', '.join(PYTHONS)}; one Python also narrows the Blender range")
    ap.add_argument("--wheels-dir", default=os.path.join(ROOT, "wheels"))
    ap.add_argument("--output-dir", help="default dist/, or dist/cp311/ etc. for a one-Python build")
    ap.add_argument("--blender", help="Blender command (default: ../shared/tools/real-blender run blender, "
                                      "else $BLENDER, else blender)")
    ap.add_argument("--download-only", action="store_true", help="fill wheels/ and stop")
    ap.add_argument("--keep-stage", action="store_true", help="keep the staging folder (printed)")
    a = ap.parse_args(argv)
    platforms = csv(a.platform, PLATFORMS, "platform")
    pythons = sorted(csv(a.python, PYTHONS, "Python"), key=lambda v: tuple(map(int, v.split("."))))
    if a.output_dir is None:
        a.output_dir = os.path.join(ROOT, "dist", *(["cp" + pythons[0].replace(".", "")] if a.python else []))
    t0 = time.perf_counter()

    chosen: dict[str, list[Wheel]] = {}
    for platform in platforms:
        chosen[platform] = [download(a.wheels_dir, d, v, py, platform) for d, v, py in wanted(pythons)]
    all_wheels = sorted({w for ws in chosen.values() for w in ws}, key=lambda w: w.filename)
    check_selection(all_wheels, pythons, platforms)
    print("Wheels (Blender platform, Python: file, size):")
    for platform in platforms:
        for py in pythons:
            for w in blender_selects(chosen[platform], py, platform).values():
                print(f"  {platform:12s} cp{py.replace('.', '')}  {w.filename}  {mb(os.path.getsize(w.path))}")
    total = sum(os.path.getsize(w.path) for w in all_wheels)
    print(f"  {len(all_wheels)} wheels, {mb(total)} in {os.path.relpath(a.wheels_dir, ROOT)}/")
    if a.download_only:
        return 0

    blender = blender_cmd(a.blender)
    with open(os.path.join(ROOT, MANIFEST), encoding="utf-8") as fh:
        committed = fh.read()
    rel = [f"./wheels/{w.filename}" for w in all_wheels]
    text = filled_manifest(committed, rel, platforms, pythons)
    version = tomllib.loads(text)["version"]
    ext_id = tomllib.loads(text)["id"]

    os.makedirs(a.output_dir, exist_ok=True)
    stage = tempfile.mkdtemp(prefix="tfv-ext-stage.", dir="/tmp")
    try:
        src = os.path.join(stage, ext_id)
        stage_tree(src)
        os.makedirs(os.path.join(src, "wheels"), exist_ok=True)
        for w in all_wheels:
            link_or_copy(w.path, os.path.join(src, "wheels", w.filename))
        with open(os.path.join(src, MANIFEST), "w", encoding="utf-8") as fh:
            fh.write(text)
        run_blender(blender, "validate", src)
        log(f"manifest with {len(rel)} wheels for {', '.join(platforms)} validated")
        for platform in platforms:          # stale zips of this version would mislead
            stale = os.path.join(a.output_dir, f"{ext_id}-{version}-{platform.replace('-', '_')}.zip")
            if os.path.exists(stale):
                os.remove(stale)
        out = run_blender(blender, "build", "--split-platforms", "--source-dir", src, "--output-dir", a.output_dir)
        log(out.replace("\n", " | "))
    finally:
        if a.keep_stage:
            log(f"staging folder kept: {stage}")
        else:
            shutil.rmtree(stage, ignore_errors=True)

    print("Zips:")
    for platform in platforms:
        path = os.path.join(a.output_dir, f"{ext_id}-{version}-{platform.replace('-', '_')}.zip")
        if not os.path.exists(path):
            sys.exit(f"build_extension: Blender did not write {path}")
        run_blender(blender, "validate", path)
        size, entries = check_zip(path, platform, [f"./wheels/{w.filename}" for w in chosen[platform]])
        code = sum(s for n, s in entries if not n.endswith(".whl"))
        print(f"  {os.path.relpath(path, ROOT)}  {mb(size)}  ({len(entries)} entries; add-on code "
              f"{code / 1e3:.0f} kB; validated)")
    print(f"build_extension: done in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
