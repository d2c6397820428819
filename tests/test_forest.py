"""Forest placement (Poisson disk on an area or a mesh) and distinct, out-of-step trees."""
import warnings

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from tree_from_video.core.errors import Cancelled, InputError
from tree_from_video.core.generate import envelopes, forest, growth, species

pytestmark = [pytest.mark.bpy53]


def test_scatter_area_spacing_bounds_determinism():
    P = forest.scatter_area(60, 40.0, 30.0, 3.0, seed=2)
    assert P.shape == (60, 2)
    assert pdist(P).min() >= 3.0 - 1e-9
    assert np.all(np.abs(P[:, 0]) <= 20.0) and np.all(np.abs(P[:, 1]) <= 15.0)
    assert np.array_equal(P, forest.scatter_area(60, 40.0, 30.0, 3.0, seed=2))
    assert not np.array_equal(P, forest.scatter_area(60, 40.0, 30.0, 3.0, seed=3))
    # a maximal Poisson-disk set is dense: well over half the hexagonal packing bound
    full = forest.poisson_disk(40.0, 30.0, 3.0, np.random.default_rng(0))
    hex_bound = 40.0 * 30.0 / (np.sqrt(3) / 2 * 9.0)
    print(f"maximal set: {len(full)} points (hexagonal packing bound {hex_bound:.0f})")
    assert 0.55 * hex_bound <= len(full) <= 1.1 * hex_bound


def test_scatter_area_too_many():
    with pytest.raises(InputError, match="only .* of 500 trees fit"):
        forest.scatter_area(500, 20.0, 20.0, 3.0, seed=0)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        P = forest.scatter_area(500, 20.0, 20.0, 3.0, seed=0, strict=False)
    assert 20 <= len(P) < 500 and any("fit" in str(x.message) for x in w)
    assert pdist(P).min() >= 3.0 - 1e-9


def test_scatter_on_mesh_area_weighted_and_spaced():
    small = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)               # area 0.5
    big = np.array([[[5, 0, 1], [8, 0, 1], [5, 1, 1]]], float)                 # area 1.5, z = 1
    tri = np.concatenate([small, big])
    P = forest.scatter_on_mesh(4000, tri, 0.0, seed=1)
    share_big = np.mean(P[:, 2] > 0.5)
    print(f"share on the 3× larger triangle: {share_big:.3f} (expected 0.75)")
    assert share_big == pytest.approx(0.75, abs=0.03)
    # points lie on their triangles: barycentric coordinates inside
    on_small = P[P[:, 2] < 0.5]
    assert np.all(on_small[:, 0] >= -1e-9) and np.all(on_small[:, 1] >= -1e-9)
    assert np.all(on_small[:, 0] + on_small[:, 1] <= 1 + 1e-9)
    ground = np.array([[[-20, -20, 0], [20, -20, 0], [20, 20, 0]], [[-20, -20, 0], [20, 20, 0], [-20, 20, 0]]], float)
    Q = forest.scatter_on_mesh(100, ground, 2.5, seed=4)
    assert Q.shape == (100, 3) and pdist(Q).min() >= 2.5 - 1e-9 and np.allclose(Q[:, 2], 0)
    with pytest.raises(InputError):
        forest.scatter_on_mesh(1000, ground, 5.0, seed=0)
    with pytest.raises(InputError):
        forest.scatter_on_mesh(3, np.zeros((0, 3, 3)), 1.0)


def test_forest_trees_distinct_and_out_of_step():
    model = species.load_species(species.species_library()["sparse"])
    env = envelopes.topiary("circle", 5.0)
    slots = forest.forest_slots(forest.scatter_area(3, 20, 20, 4.0, seed=1), seed=9)
    assert len({s.seed for s in slots}) == 3 and len({round(s.time_offset_s, 6) for s in slots}) == 3
    trees = forest.generate_forest(model, env, slots, growth.GrowParams(n_frames=96, node_budget=120))
    assert len(trees) == 3
    assert len({t.n_nodes for t in trees}) > 1 or not np.allclose(trees[0].nodes3d[0], trees[1].nodes3d[0])
    for t, s in zip(trees, slots):
        assert np.max(t.meta["envelope"]["z"]) == pytest.approx(5.0 * s.scale, rel=0.02)
    # the trunks' sway (first node above the base... the top of the trunk) is not in lockstep
    sway = [t.nodes3d[:, 1:, 0].mean(1) - t.nodes3d[:, 1:, 0].mean() for t in trees]
    c = [abs(np.corrcoef(sway[i], sway[j])[0, 1]) for i in range(3) for j in range(i + 1, 3)]
    print(f"correlation of the trees' sway: {np.round(c, 3)}")
    assert max(c) < 0.9


def test_forest_cancel():
    model = species.load_species(species.species_library()["broad"])
    env = envelopes.topiary("triangle", 5.0)
    slots = forest.forest_slots(np.zeros((5, 2)), seed=1)
    seen = []

    def progress(stage, frac):
        seen.append(frac)
        return frac < 0.3
    with pytest.raises(Cancelled):
        forest.generate_forest(model, env, slots, growth.GrowParams(n_frames=10), progress=progress)
    assert max(seen) < 0.6
