"""scripts/build_extension.py without network or Blender: which wheel Blender would install, and the
manifest it writes (the committed one keeps ``wheels = []``)."""
import importlib.util
import os
import sys
import tomllib

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_spec = importlib.util.spec_from_file_location("build_extension", os.path.join(ROOT, "scripts", "build_extension.py"))
be = importlib.util.module_from_spec(_spec)
sys.modules["build_extension"] = be        # dataclasses look their module up there
_spec.loader.exec_module(be)

SCIPY_311 = "scipy-1.13.1-cp311-cp311-manylinux_2_17_x86_64.manylinux2014_x86_64.whl"
SCIPY_313 = "scipy-1.17.1-cp313-cp313-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl"
CV_411 = "opencv_contrib_python_headless-4.11.0.86-cp37-abi3-manylinux_2_17_x86_64.manylinux2014_x86_64.whl"
CV_500 = "opencv_contrib_python_headless-5.0.0.93-cp37-abi3-manylinux2014_x86_64.manylinux_2_17_x86_64.whl"


def W(name):
    return be.Wheel("/w/" + name)


def test_python_tags_follow_blender():
    assert W(SCIPY_311).fits_python("3.11") and not W(SCIPY_311).fits_python("3.13")
    assert W(SCIPY_313).fits_python("3.13") and not W(SCIPY_313).fits_python("3.11")
    assert W(CV_411).fits_python("3.11") and W(CV_411).fits_python("3.13")     # abi3: every Python >= 3.7


def test_platform_tags_follow_blender():
    assert W(SCIPY_311).fits_platform("linux-x64") and not W(SCIPY_311).fits_platform("windows-x64")
    assert W("scipy-1.13.1-cp311-cp311-win_amd64.whl").fits_platform("windows-x64")
    uni = W("x-1.0-cp311-cp311-macosx_10_9_universal2.whl")
    assert uni.fits_platform("macos-arm64") and uni.fits_platform("macos-x64") and not uni.fits_platform("linux-x64")
    assert not W("scipy-1.13.1-cp311-cp311-macosx_12_0_arm64.whl").fits_platform("macos-x64")


def test_pinned_set_is_what_blender_installs():
    wheels = [W(SCIPY_311), W(SCIPY_313), W(CV_411)]
    be.check_selection(wheels, ["3.11", "3.13"], ["linux-x64"])             # no SystemExit
    assert {w.filename for w in be.blender_selects(wheels, "3.11", "linux-x64").values()} == {SCIPY_311, CV_411}
    assert {w.filename for w in be.blender_selects(wheels, "3.13", "linux-x64").values()} == {SCIPY_313, CV_411}


def test_a_newer_opencv_for_cp313_would_reach_python_311(monkeypatch):
    # OpenCV wheels are abi3: Blender keeps the newest for every Python, so 5.0 (numpy 2 only) would
    # be installed in Blender 4.2-5.0 (numpy 1.26) too. The build must refuse such a set.
    monkeypatch.setattr(be, "SHARED", {})
    monkeypatch.setattr(be, "PYTHONS", {
        "3.11": ("", {"scipy": "1.13.1", "opencv-contrib-python-headless": "4.11.0.86"}),
        "3.13": ("", {"scipy": "1.17.1", "opencv-contrib-python-headless": "5.0.0.93"})})
    wheels = [W(SCIPY_311), W(SCIPY_313), W(CV_411), W(CV_500)]
    assert be.blender_selects(wheels, "3.11", "linux-x64")["opencv_contrib_python_headless"].version == "5.0.0.93"
    with pytest.raises(SystemExit, match="Python 3.11"):
        be.check_selection(wheels, ["3.11", "3.13"], ["linux-x64"])


def test_committed_manifest_keeps_wheels_empty_and_build_fills_a_copy():
    with open(os.path.join(ROOT, "blender_manifest.toml"), encoding="utf-8") as fh:
        text = fh.read()
    committed = tomllib.loads(text)
    assert committed["wheels"] == [] and "platforms" not in committed
    excluded = committed["build"]["paths_exclude_pattern"]
    for pattern in ("/tests/", "/benchmarks/", "/scripts/", "/sample_videos/", "/wheels/", "*.mp4", "*.npz"):
        assert pattern in excluded

    wheels = ["./wheels/" + SCIPY_311, "./wheels/" + CV_411]
    filled = tomllib.loads(be.filled_manifest(text, wheels, ["linux-x64"], ["3.11", "3.13"]))
    assert filled["wheels"] == wheels and filled["platforms"] == ["linux-x64"]
    assert "blender_version_max" not in filled
    assert {k: v for k, v in filled.items() if k not in ("wheels", "platforms")} == \
        {k: v for k, v in committed.items() if k != "wheels"}

    only311 = tomllib.loads(be.filled_manifest(text, wheels, ["linux-x64"], ["3.11"]))
    assert (only311["blender_version_min"], only311["blender_version_max"]) == ("4.2.0", "5.1.0")
    only313 = tomllib.loads(be.filled_manifest(text, wheels, ["linux-x64"], ["3.13"]))
    assert only313["blender_version_min"] == "5.1.0" and "blender_version_max" not in only313
