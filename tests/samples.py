"""Synthetic sample videos for tests: the committed ones and freshly generated variants."""
from __future__ import annotations

import os

import numpy as np

from tree_from_video.sample_videos import synth_tree

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COMMITTED = os.path.join(ROOT, "sample_videos")


def motion_truth_harness():
    """benchmarks/motion_truth.py as a module (issue 18's measurement harness)."""
    import importlib.util
    import sys
    spec = importlib.util.spec_from_file_location("motion_truth", os.path.join(ROOT, "benchmarks", "motion_truth.py"))
    mod = importlib.util.module_from_spec(spec)
    sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
    spec.loader.exec_module(mod)
    return mod


def committed(name: str) -> str:
    """Folder of a committed sample (video.mp4, outline.json, mask.png, truth.npz)."""
    return os.path.join(COMMITTED, name)


def generate(variant: str, folder: str, **overrides) -> str:
    """Generate ``variant`` into ``folder`` (once) and return the folder."""
    if not os.path.exists(os.path.join(folder, "truth.npz")):
        synth_tree.generate(synth_tree.config_for(variant, **overrides), folder)
    return folder


def video_path(folder: str) -> str:
    """The video of a sample folder: video.mp4, or video.mkv for a variable-frame-rate sample."""
    for name in ("video.mp4", "video.mkv"):
        path = os.path.join(folder, name)
        if os.path.exists(path):
            return path
    raise FileNotFoundError(f"no video.mp4 or video.mkv in {folder}")


def load_truth(folder: str) -> dict:
    with np.load(os.path.join(folder, "truth.npz"), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def plain_settings(**kw):
    """``pipeline.Settings`` with no twigs and straight, round tubes (twig depth 0, curliness 0, bark
    none): the settings the measured tests and the shipped species were made with, before the
    product's defaults (twigs 2, curliness 0.3, rough bark) moved into the core's dataclasses."""
    from tree_from_video.core import pipeline
    from tree_from_video.core.detail.twigs import TwigParams
    kw.setdefault("twigs", TwigParams(depth=0))
    kw.setdefault("curliness", 0.0)
    kw.setdefault("bark", "none")
    return pipeline.Settings(**kw)
