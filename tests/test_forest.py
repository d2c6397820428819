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


def test_variants_are_dealt_evenly_and_numbered_by_first_slot():
    slots = forest.forest_slots(np.zeros((12, 2)), seed=5, variants=3)
    v = np.array([s.variant for s in slots])
    assert sorted(np.bincount(v)) == [4, 4, 4]
    assert [int(x) for x in v[np.sort(np.unique(v, return_index=True)[1])]] == [0, 1, 2]   # first-seen order
    for k in range(3):                              # a variant's slots carry its one seed
        assert len({s.seed for s in slots if s.variant == k}) == 1
    assert len({s.seed for s in slots}) == 3
    assert len({round(s.time_offset_s, 6) for s in slots}) == 12 and len({s.rotation_z for s in slots}) == 12
    # 0 or ≥ n variants: every slot its own tree, as before
    own = forest.forest_slots(np.zeros((4, 2)), seed=5)
    assert [s.variant for s in own] == [0, 1, 2, 3] and len({s.seed for s in own}) == 4
    assert [s.variant for s in forest.forest_slots(np.zeros((4, 2)), seed=5, variants=9)] == [0, 1, 2, 3]
    assert forest.variant_count(slots) == 3 and forest.shares_variants(slots) and not forest.shares_variants(own)
    with pytest.raises(InputError, match="variants"):
        forest.forest_slots(np.zeros((4, 2)), variants=-1)


def test_instance_offsets_by_hand():
    """Offsets are each slot's time offset minus its variant's first slot's, in frames, wrapped
    round the period: 24 fps, period 48 frames."""
    S = forest.TreeSlot
    z = np.zeros(3)
    slots = [S(z, 0.0, 1, 1.0, z, 1.0, 0), S(z, 0.0, 2, 0.5, z, 1.0, 1), S(z, 0.0, 1, 2.5, z, 1.0, 0),
             S(z, 0.0, 1, 0.25, z, 1.0, 0), S(z, 0.0, 2, 3.0, z, 1.0, 1)]
    got = forest.instance_offsets(slots, 24.0, 48)
    # (2.5 − 1) · 24 = 36; (0.25 − 1) · 24 = −18 → 30; (3 − 0.5) · 24 = 60 → 12
    assert got.tolist() == [0, 0, 36, 30, 12]


def test_shared_variants_sway_in_a_loop_and_refuse_a_recording():
    model = species.load_species(species.species_library()["sparse"])
    env = envelopes.topiary("circle", 5.0)
    slots = forest.forest_slots(forest.scatter_area(5, 30, 30, 4.0, seed=2), seed=4, variants=2)
    trees = forest.generate_forest(model, env, slots, growth.GrowParams(n_frames=73, node_budget=80))
    assert len(trees) == 2
    for v, t in enumerate(trees):
        first = next(s for s in slots if s.variant == v)
        assert t.meta["periodic"]["frames"] == 72 and t.n_frames == 73
        assert np.abs(t.nodes3d[-1] - t.nodes3d[0]).max() < 1e-4 * np.ptp(t.nodes3d[0][:, 2])   # a loop
        assert np.max(t.meta["envelope"]["z"]) == pytest.approx(5.0 * first.scale, rel=0.02)
        assert t.meta["seed"] == first.seed
    with pytest.raises(InputError, match="Variants to 0"):
        forest.generate_forest(model, env, slots, growth.GrowParams(n_frames=20), audio=np.ones(20))
