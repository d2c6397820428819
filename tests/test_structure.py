"""The layout keeps its promises: imports point one way with no cycle, core/ imports no bpy, no
module grows past 600 lines, modules are reached by ordinary imports (one loader), and every
``Tree3D.meta`` key a stage reads is documented and written by a stage."""
from __future__ import annotations

import ast
import os
import re

import pytest

from samples import ROOT, plain_settings

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

PACKAGE = "tree_from_video"
SKIP = {".venv", ".git", "dist", "wheels", "out", "__pycache__", "tests", "benchmarks", "scripts", "sample_videos"}


def package_files() -> dict[str, str]:
    """{dotted module: path} of every module of the add-on package (tests, tools and samples left out)."""
    out = {}
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = sorted(d for d in dirs if d not in SKIP)
        for f in files:
            if not f.endswith(".py"):
                continue
            rel = os.path.relpath(os.path.join(folder, f), ROOT)[:-3].split(os.sep)
            if rel[-1] == "__init__":
                rel = rel[:-1]
            out[".".join([PACKAGE, *rel])] = os.path.join(folder, f)
    return out


def imports_of(module: str, path: str, known: set[str]) -> set[str]:
    """Package modules imported anywhere in ``path`` (function-level imports included)."""
    is_pkg = path.endswith("__init__.py")
    here = module.split(".") if is_pkg else module.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(open(path, encoding="utf-8").read())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[:len(here) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            subs = [f"{target}.{a.name}" for a in node.names]
            names = subs if any(n in known for n in subs) else [target]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        for n in names:
            if n in known and n != module:
                found.add(n)
    return found


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    files = package_files()
    known = set(files)
    return {m: imports_of(m, p, known) for m, p in files.items()}


def test_every_relative_import_names_a_module_of_the_package():
    """A mistyped relative import inside a function only fails when that code runs: find it here."""
    files = package_files()
    bad = []
    for module, path in files.items():
        here = module.split(".") if path.endswith("__init__.py") else module.split(".")[:-1]
        for node in ast.walk(ast.parse(open(path, encoding="utf-8").read())):
            if isinstance(node, ast.ImportFrom) and node.level:
                target = ".".join(here[:len(here) - node.level + 1] + ([node.module] if node.module else []))
                if target not in files:
                    bad.append((os.path.relpath(path, ROOT), node.lineno, target))
    assert not bad, bad


#: core's stage subpackages, in the order data flows
STAGES = ("reconstruct", "detail", "generate", "asset")


def test_the_stages_are_subpackages_of_core():
    core = os.path.join(ROOT, "core")
    for stage in STAGES:
        assert os.path.isfile(os.path.join(core, stage, "__init__.py"))
    doc = ast.get_docstring(ast.parse(open(os.path.join(core, "__init__.py"), encoding="utf-8").read()))
    assert doc and all(f"{stage}/" in doc for stage in STAGES)


def test_no_import_cycle(graph):
    """Tarjan's strongly connected components over the module graph: none larger than one."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    cycles = []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    # a package's __init__ importing its own submodules (register()) is no cycle of the code's layers:
    # drop parent packages from each component before judging it
    real = [[m for m in c if not any(o.startswith(m + ".") for o in c)] for c in cycles]
    assert not [c for c in real if len(c) > 1], real


def _stage(module: str) -> str | None:
    parts = module.split(".")
    if len(parts) >= 3 and parts[1] == "core":
        return parts[2] if parts[2] in STAGES else "shared"
    return None


#: the modules that string the stages end to end (any stage may be called from them)
END_TO_END = (f"{PACKAGE}.core.pipeline", f"{PACKAGE}.core.jobs")


def test_imports_point_one_way(graph):
    allowed = {"shared": {"shared"}, "reconstruct": {"shared", "reconstruct"},
               "detail": {"shared", "reconstruct", "detail"},
               "generate": {"shared", "reconstruct", "detail", "generate"},
               "asset": {"shared", "detail", "asset"}}          # what writers copy: a built tree's arrays
    bad = []
    for m, deps in graph.items():
        s = _stage(m)
        if s is None or m in END_TO_END:                     # the end-to-end pipeline and jobs call every stage
            continue
        for d in deps:
            ds = _stage(d)
            if ds is None:
                bad.append((m, d))                            # core imports nothing outside core
            elif d not in END_TO_END and ds not in allowed[s]:
                bad.append((m, d))
    assert not bad, bad


def test_core_is_pure_python_and_small():
    core = os.path.join(ROOT, "core")
    for folder, _, files in os.walk(core):
        for f in files:
            if f.endswith(".py"):
                path = os.path.join(folder, f)
                text = open(path, encoding="utf-8").read()
                assert not re.search(r"^\s*(import|from)\s+(bpy|mathutils|bmesh)\b", text, re.M), path
                assert text.count("\n") <= 600, f"{path}: {text.count(chr(10))} lines"


def test_operators_hold_operator_classes_only():
    ops = os.path.join(ROOT, "operators")
    for f in sorted(os.listdir(ops)):
        if not f.endswith(".py") or f == "__init__.py":
            continue
        tree = ast.parse(open(os.path.join(ops, f), encoding="utf-8").read())
        classes = [n for n in tree.body if isinstance(n, ast.ClassDef)]
        assert classes, f
        for c in classes:                  # jobs.py is the shared modal-job base (JobOperator, SteppedJob)
            assert c.name.startswith("TREE_OT_") or f == "jobs.py", (f, c.name)
        # no operator module reaches into another one's private names
        for n in ast.walk(tree):
            if isinstance(n, ast.ImportFrom) and n.level == 1 and n.module and not n.module.startswith("scene"):
                assert all(not a.name.startswith("_") for a in n.names), (f, n.module)


def test_no_string_imports_outside_the_loader():
    hits = []
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if d not in {".venv", ".git", "dist", "wheels", "out", "__pycache__"}]
        for f in files:
            path = os.path.join(folder, f)
            if f.endswith(".py") and os.path.relpath(path, ROOT) not in ("package_loader.py", "tests/test_structure.py"):
                text = open(path, encoding="utf-8").read()
                if re.search(r"import_module\(f?[\"'][^\"']*(core|operators|ui|cli)", text) \
                        or "spec_from_file_location(\"tree_from_video\"" in text \
                        or "spec_from_file_location(PACKAGE" in text:
                    hits.append(os.path.relpath(path, ROOT))
    assert not hits, hits


def test_batch_shim_is_thin():
    text = open(os.path.join(ROOT, "batch.py"), encoding="utf-8").read()
    assert text.count("\n") <= 40 and "load_module(\"cli\")" in text


# ----------------------------------------------------------------------------- Tree3D.meta

META_READ = re.compile(r"\.meta(?:\[|\.get\()\s*\"([a-z_0-9]+)\"")


def meta_reads() -> dict[str, str]:
    """{key: first file} of every ``x.meta["key"]`` / ``x.meta.get("key")`` in the package."""
    out: dict[str, str] = {}
    for path in package_files().values():
        for k in META_READ.findall(open(path, encoding="utf-8").read()):
            out.setdefault(k, os.path.relpath(path, ROOT))
    return out


def test_meta_keys_are_typed_and_documented():
    from tree_from_video.core.meta import KEYS, TreeMeta
    assert set(TreeMeta.__annotations__) == set(KEYS)
    assert all(k.unit and k.writers and k.doc for k in KEYS.values())
    unknown = {k: f for k, f in meta_reads().items() if k not in KEYS}
    assert not unknown, f"meta keys read but not in core/meta.py: {unknown}"


def test_every_key_a_tree_carries_is_documented_and_every_read_key_is_written():
    """A reconstruction (twigs, leaves, branch fit), what the batch job adds, a generated tree and
    a tree saved and loaded again carry only documented keys; every key a stage reads is among
    what they carry."""
    from tree_from_video.core import pipeline
    from tree_from_video.core.detail.twigs import TwigParams
    from tree_from_video.core.generate import growth, species
    from tree_from_video.core.generate.envelopes import envelope_from_any
    from tree_from_video.core.loop import loop_tree
    from tree_from_video.core.meta import KEYS
    from tree_from_video.core.tree3d import load_tree, save_tree
    video = os.path.join(ROOT, "sample_videos", "broad")
    s = plain_settings(frames="0:24", twigs=TwigParams(depth=1))
    res = pipeline.run(os.path.join(video, "video.mp4"), os.path.join(video, "outline.json"), s)
    tree = pipeline.build_3d(res, s)
    import json
    import tempfile
    with tempfile.TemporaryDirectory() as d:             # a shot of two trees: the tree and the house
        two = os.path.join(d, "two.json")
        poly = json.load(open(os.path.join(video, "outline.json")))["polygon"]
        json.dump([poly, [[340, 200], [470, 200], [470, 330], [340, 330]]], open(two, "w"))
        shot = pipeline.build_shot(pipeline.run_all(os.path.join(video, "video.mp4"), two, plain_settings(frames="0:8")),
                                   plain_settings(frames="0:8"))
    model = species.load_species(species.species_library()["broad"])
    env = envelope_from_any("circle", 8.0)
    gen = growth.grow_tree(model, env, growth.GrowParams(seed=1, node_budget=60, n_frames=12))
    # a generated loop, looped (nothing blended)
    looped = loop_tree(growth.grow_tree(model, env, growth.GrowParams(seed=1, node_budget=30, loop_s=0.5)), 0.5)[0]
    cli_tree = ast.parse(open(os.path.join(ROOT, "cli.py"), encoding="utf-8").read())
    cli_keys = {k.value for n in ast.walk(cli_tree) if isinstance(n, ast.Assign)
                and any(isinstance(t, ast.Name) and t.id == "meta" for t in n.targets)
                and isinstance(n.value, ast.Dict) for k in n.value.keys if isinstance(k, ast.Constant)}
    assert cli_keys >= {"video", "frames", "levels", "scale", "version"}
    carried = set(tree.meta) | set(gen.meta) | cli_keys | set(shot[1].meta) | set(looped.meta)
    assert carried <= set(KEYS), carried - set(KEYS)
    with tempfile.TemporaryDirectory() as d:
        save_tree(os.path.join(d, "t.npz"), tree)
        carried |= set(load_tree(os.path.join(d, "t.npz")).meta)
    assert carried <= set(KEYS), carried - set(KEYS)
    never_written = {k: f for k, f in meta_reads().items() if k not in carried}
    assert not never_written, f"meta keys read that no stage writes: {never_written}"
    for k in ("metres_per_px", "base_px", "envelope", "mesh", "video_size", "twigs", "branch_fit"):
        assert k in tree.meta, k
    assert tree.meta["video_size"] == [int(res.outline.mask.shape[1]), int(res.outline.mask.shape[0])]
