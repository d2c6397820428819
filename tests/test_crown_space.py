"""Varied crowns in 3D (issue 36 part 2, ``--envelope-variation``; core/generate/crown_space.py): an
envelope's pinned contour, the contour seen from behind, the shipped library's contours, and
generated trees that each grow in their own crown (width over height spread ≥ 0.05, within the
contour space's range, the tree inside its own envelope) with their own leaf colour within the
species' range; V = 0 is the tree grown without it, bit for bit."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from tree_from_video.core.generate.batch import load_species_spec
from tree_from_video.core.generate.crown_space import (
    COUNTS,
    N_CONTOUR,
    contour_space,
    envelope_contour,
    varied_contour,
    varied_envelope,
)
from tree_from_video.core.generate.envelopes import envelope_from_polygon, region_of, topiary
from tree_from_video.core.generate.exemplars import mirror_pinned
from tree_from_video.core.generate.growth import GrowParams, grow_tree
from tree_from_video.core.generate.species import SpeciesModel, library_contours, load_species, species_library

from samples import ROOT


def aspect(c: np.ndarray) -> float:
    return float(np.ptp(c[:, 0]) / np.ptp(c[:, 1]))


def test_envelope_contour_is_pinned():
    env = topiary("triangle", 10.0, 6.0, stem_frac=0.2)
    c = envelope_contour(env)
    assert c.shape == (N_CONTOUR, 2)
    assert abs(c[:, 1].min()) < 1e-9 and abs(np.ptp(c[:, 1]) - 1.0) < 1e-9          # height 1, base at 0
    assert abs(c[0, 0]) < 0.02 and c[0, 1] < 0.01                                  # B: the stem's foot
    r, l_ = c[COUNTS[0]], c[COUNTS[0] + COUNTS[1]]
    # R and L where the outline meets the crown's baseline: the stem's top (0.2 of the height), right of left
    assert r[0] > l_[0] and abs(r[1] - 0.2) < 0.05 and abs(l_[1] - 0.2) < 0.05
    assert abs(aspect(c) - 0.6) < 0.02                                              # 6 m wide, 10 m tall
    m = mirror_pinned(c)
    assert np.allclose(mirror_pinned(m), c)                                         # twice: itself
    assert np.allclose(m[0], c[0]) and np.allclose(m[COUNTS[0] + COUNTS[1]], c[COUNTS[0]] * [-1, 1], atol=1e-9)


def test_library_species_keep_their_contours():
    for name, path in species_library().items():
        model = load_species(path)
        assert len(model.contours) == 1, name
        c = model.contours[0]
        assert c.shape == (N_CONTOUR, 2) and abs(np.ptp(c[:, 1]) - 1.0) < 1e-3, name
        rng = model.leaves.get("colour_range") if model.leaves else None
        if name != "palm":                               # a palm's fronds keep no leaf clusters
            assert rng is not None and np.all(np.asarray(rng[0]) <= np.asarray(rng[1]) + 1e-9), name
        # JSON round trip keeps them
        again = SpeciesModel.from_json(json.loads(json.dumps(model.to_json())))
        assert np.allclose(again.contours[0], c, atol=1e-4)
    space = contour_space([], library_contours())
    assert len(space) == 2 * len(species_library())                                 # and each from behind


def test_varied_contour_is_a_convex_mix_within_the_space():
    space = contour_space([], library_contours())
    src = envelope_contour(topiary("circle", 10.0))
    lo = min(aspect(c) for c in space + [src])
    hi = max(aspect(c) for c in space + [src])
    rng = np.random.default_rng(3)
    got = []
    for v in (0.3, 0.7, 1.0):
        for _ in range(5):
            c, w = varied_contour(src, space, v, rng)
            assert np.isclose(w.sum(), 1.0) and (w >= 0).all()
            got.append(aspect(c))
            assert lo - 0.02 <= got[-1] <= hi + 0.02
    print(f"space width/height {lo:.3f}..{hi:.3f}; varied {np.round(got, 3)}")
    assert np.ptp(got) >= 0.1
    env = topiary("circle", 10.0)
    same, info = varied_envelope(env, space, 0.0, rng)
    assert same is env and info["variation"] == 0.0


@pytest.mark.slow
def test_generated_trees_grow_in_their_own_crowns():
    model = load_species_spec("broad")[0]
    env = topiary("circle", 10.0)
    base = GrowParams(seed=5, n_frames=8, node_budget=150, leaf_density=1.0, twig_depth=0)
    plain = grow_tree(model, env, base)
    zero = grow_tree(model, env, GrowParams(**{**base.__dict__, "envelope_variation": 0.0}))
    assert np.array_equal(plain.nodes3d, zero.nodes3d) and "envelope_variation" not in zero.meta
    lo_c, hi_c = np.asarray(model.leaves["colour_range"])
    aspects, colours = [], []
    for seed in range(20, 26):
        t = grow_tree(model, env, GrowParams(**{**base.__dict__, "seed": seed, "envelope_variation": 0.6}))
        info = t.meta["envelope_variation"]
        poly = np.asarray(t.meta["envelope"]["polygon"])
        aspects.append(float(np.ptp(poly[:, 0]) / np.ptp(poly[:, 1])))
        assert abs(aspects[-1] - info["width_over_height"][1]) < 0.03
        # the tree fills its own envelope: its rest nodes inside the varied outline (unvaried trees:
        # 0.95-0.99 inside the circle; a narrower varied crown is filled a little past its edge)
        rest = t.nodes3d[0][:, [0, 2]].astype(np.float64)
        inside = region_of(t_env(t)).contains(rest).mean()
        assert inside >= 0.85, inside
        c = np.asarray(info["leaf_colour"])
        colours.append(c)
        base_c = np.asarray(model.leaves["colour"])
        assert np.all(c >= np.minimum(base_c, lo_c) - 1e-3) and np.all(c <= np.maximum(base_c, hi_c) + 1e-3)
    print(f"width/height of six trees at V = 0.6: {np.round(aspects, 3)}; the circle's {aspect(envelope_contour(env)):.3f}")
    assert np.ptp(aspects) >= 0.05
    space = contour_space(model.contours, library_contours()) + [envelope_contour(env)]
    lo, hi = min(aspect(c) for c in space), max(aspect(c) for c in space)
    assert lo - 0.03 <= min(aspects) and max(aspects) <= hi + 0.03
    assert np.ptp(np.asarray(colours), axis=0).max() > 0.005


def t_env(tree):
    return envelope_from_polygon(np.asarray(tree.meta["envelope"]["polygon"]))


@pytest.mark.slow
def test_batch_envelope_variation(tmp_path):
    out = tmp_path / "out"
    p = subprocess.run([sys.executable, os.path.join(ROOT, "batch.py"), "--generate", "2", "--species", "conifer",
                        "--envelope-variation", "0.5", "--seconds", "1", "--nodes", "120", "--out", str(out),
                        "--quiet"], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    from tree_from_video.core.tree3d import load_tree
    metas = [load_tree(str(out / f"tree_00{i}" / "tree3d.npz")).meta for i in range(2)]
    assert all(m["envelope_variation"]["variation"] == 0.5 for m in metas)
    assert metas[0]["envelope"]["polygon"] != metas[1]["envelope"]["polygon"]
    bad = subprocess.run([sys.executable, os.path.join(ROOT, "batch.py"), "--generate", "1", "--species", "broad",
                          "--envelope-variation", "1.5", "--out", str(tmp_path / "bad")],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "--envelope-variation" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1

