"""Load the repository root as the package ``tree_from_video`` (no Blender needed for core tests)."""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from package_loader import load_package  # noqa: E402

load_package()


# --- shared fixtures: every sample variant generated once per session and run through the core ---
import pytest  # noqa: E402

BAR_VARIANTS = ("broad", "conifer", "sparse", "hard", "grey", "gentle")
ALL_VARIANTS = BAR_VARIANTS + ("dense",)


@pytest.fixture(scope="session")
def runs(tmp_path_factory):
    """{variant: {"truth", "folder", "traced": Result, "paper": Result}} for every variant."""
    from samples import generate, load_truth, plain_settings
    from tree_from_video.core import pipeline
    base = tmp_path_factory.mktemp("variants")
    out = {}
    for v in ALL_VARIANTS:
        folder = generate(v, str(base / v))
        entry = {"truth": load_truth(folder), "folder": folder}
        for kind in ("traced", "paper"):
            entry[kind] = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"),
                                       plain_settings(skeleton=kind))
        out[v] = entry
    return out


@pytest.fixture(scope="session")
def scores(runs):
    from groundtruth import score
    return {v: {k: score(e[k].skeleton.parents, e[k].skeleton.nodes2d, e["truth"]) for k in ("traced", "paper")}
            for v, e in runs.items()}



