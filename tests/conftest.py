"""Load the repository root as the package ``tree_from_video`` (no Blender needed for core tests)."""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from package_loader import load_package  # noqa: E402

load_package()


# --- shared fixtures: every sample variant generated once per session and run through the core ---
import pytest  # noqa: E402
import report  # noqa: E402

BAR_VARIANTS = ("broad", "conifer", "sparse", "hard", "grey", "gentle")
ALL_VARIANTS = BAR_VARIANTS + ("dense",)


@pytest.fixture(scope="session")
def runs(tmp_path_factory):
    """{variant: {"truth", "folder", "traced": Result, "paper": Result}} for every variant."""
    from tree_from_video.core import pipeline

    from samples import generate, load_truth, plain_settings
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
    """{variant: {kind: Score}} of the 2D skeletons against the truth (a report table, too)."""
    from groundtruth import score
    out = {v: {k: score(e[k].skeleton.parents, e[k].skeleton.nodes2d, e["truth"]) for k in ("traced", "paper")}
           for v, e in runs.items()}
    lines = [f"{'variant':<9}{'kind':<8}{'chamfer1':>9}{'chamferF':>9}{'cover':>7}{'tipcorr':>8}{'df Hz':>7}{'nodes':>6}"]
    for v, by_kind in out.items():
        for k, s in by_kind.items():
            lines.append(f"{v:<9}{k:<8}{100 * s.chamfer1:8.2f}%{100 * s.chamfer_all:8.2f}%{s.coverage:7.2f}"
                         f"{s.tip_corr:8.2f}{s.freq_err:7.3f}{s.n_nodes:6d}")
    report.add("2D skeleton vs truth (tests/test_skeleton_truth.py)", lines)
    return out


# --- the tables under pytest-xdist (scripts/test.sh runs the wheel's tests on every core): each
# worker collects its own, writes them to a folder the controller made, and the controller prints them
@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node):
    """(xdist controller) hand every worker the folder its tables go to."""
    config = node.config
    if not hasattr(config, "_tfv_tables"):
        import tempfile
        config._tfv_tables = tempfile.mkdtemp(prefix="tfv-tables-")
    node.workerinput["tfv_tables"] = config._tfv_tables


def pytest_sessionfinish(session):
    folder = getattr(session.config, "workerinput", {}).get("tfv_tables")
    if folder and report.TABLES:
        import json
        name = os.path.join(folder, session.config.workerinput["workerid"] + ".json")
        with open(name + ".tmp", "w", encoding="utf-8") as fh:
            json.dump(report.TABLES, fh)
        os.replace(name + ".tmp", name)


def _workers_tables(config) -> dict[str, list[str]]:
    """The tables the xdist workers wrote (a table split over two workers keeps one header)."""
    import glob
    import json
    import shutil
    folder = getattr(config, "_tfv_tables", None)
    tables: dict[str, list[str]] = {}
    if not folder:
        return tables
    for name in sorted(glob.glob(os.path.join(folder, "*.json"))):
        with open(name, encoding="utf-8") as fh:
            for title, lines in json.load(fh).items():
                have = tables.setdefault(title, [])
                have.extend(lines[1:] if have and lines and lines[0] == have[0] else lines)
    shutil.rmtree(folder, ignore_errors=True)
    return tables


def pytest_terminal_summary(terminalreporter, config):
    """Print the measurement tables the tests collected (tests/report.py), in this process or in
    the xdist workers."""
    for title, lines in {**report.TABLES, **_workers_tables(config)}.items():
        terminalreporter.section(title)
        for line in lines:
            terminalreporter.write_line(line)



