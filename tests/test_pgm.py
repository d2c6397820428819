"""Species model (paper §5.1-5.2): Dirichlet ML fit, bifurcation and motion features, JSON files."""
import json
import math
import os

import numpy as np
import pytest
from scipy.special import digamma

from tree_from_video.core.errors import InputError
from tree_from_video.core.generate import dirichlet, features, species
from tree_from_video.core.tree3d import Tree3D

from generation_data import source_model, source_tree

pytestmark = [pytest.mark.bpy53]

PARAMS = {
    "moderate": [2.0, 5.0, 3.0],
    "skewed": [0.3, 1.0, 8.0],
    "very skewed": [30.0, 5.0, 1.5],
    "sparse": [0.5, 0.5, 0.5],
    "concentrated": [50.0, 100.0, 200.0],
    "motion-like K=12": [3.3, 1.8, 1.1, 1.4, 2.4, 4.3, 1.6, 1.3, 0.85, 0.24, 0.77, 0.14],
}


@pytest.mark.parametrize("name", list(PARAMS))
def test_dirichlet_recovers_parameters(name):
    alpha = np.array(PARAMS[name])
    X = np.random.default_rng(7).dirichlet(alpha, 2000)
    fit = dirichlet.fit_dirichlet(X)
    err = np.abs(fit.alpha / alpha - 1)
    print(f"{name}: alpha {np.round(fit.alpha, 3)} max rel err {err.max():.3f} in {fit.iterations} it")
    assert fit.fallback is None
    assert err.max() <= 0.10
    h = np.diff(fit.loglik)
    assert len(h) >= 1 and np.all(h > 0)          # the log-likelihood rises at every iteration


def test_fixed_point_alone_increases_likelihood():
    """Minka's fixed point (no Newton) never lowers the likelihood: ten plain steps by hand."""
    alpha_true = np.array([4.0, 1.5, 0.7])
    Z = np.random.default_rng(3).dirichlet(alpha_true, 500)
    ml = np.log(Z).mean(0)
    a = np.ones(3)
    lls = [dirichlet.dirichlet_loglik(a, ml)]
    for _ in range(10):
        a = dirichlet.inv_digamma(digamma(a.sum()) + ml)
        lls.append(dirichlet.dirichlet_loglik(a, ml))
    assert np.all(np.diff(lls) > 0)
    assert np.abs(dirichlet.fit_dirichlet(Z).alpha / alpha_true - 1).max() < 0.15


def test_inverse_digamma_and_loglik_hand_cases():
    y = np.linspace(-8, 6, 57)
    assert np.max(np.abs(digamma(dirichlet.inv_digamma(y)) - y)) < 1e-10
    # Eq. 11: D(z | 1, 1, 1) = Γ(3) = 2 everywhere; D(z | 2, 1) = 2 z1 → z = (0.25, 0.75): log 0.5
    assert dirichlet.dirichlet_loglik([1, 1, 1], np.log([0.2, 0.3, 0.5])) == pytest.approx(math.log(2))
    assert dirichlet.dirichlet_loglik([2, 1], np.log([0.25, 0.75])) == pytest.approx(math.log(0.5))


@pytest.mark.parametrize("case", ["empty", "one", "fewer than K", "zeros", "identical", "nan rows", "negative"])
def test_dirichlet_degenerate_data_never_nan(case):
    rng = np.random.default_rng(1)
    X = {"empty": np.zeros((0, 3)),
         "one": np.array([[0.2, 0.3, 0.5]]),
         "fewer than K": rng.dirichlet(np.ones(6), 4),
         "zeros": np.vstack([rng.dirichlet([2, 2, 2], 50), [[0.0, 0.5, 0.5], [0.3, 0.0, 0.7]]]),
         "identical": np.tile([0.2, 0.3, 0.5], (40, 1)),
         "nan rows": np.vstack([rng.dirichlet([2, 3, 4], 50), [[np.nan, 0.5, 0.5]]]),
         "negative": np.vstack([rng.dirichlet([2, 3, 4], 50), [[-0.1, 0.6, 0.5]]])}[case]
    fit = dirichlet.fit_dirichlet(X)
    assert np.all(np.isfinite(fit.alpha)) and np.all(fit.alpha > 0)
    assert np.all(np.isfinite(fit.loglik))
    assert fit.fallback is not None or case == "nan rows"
    s = fit.sample(np.random.default_rng(0), 10)
    assert np.all(np.isfinite(s)) and np.allclose(s.sum(1), 1)
    if case in ("one", "identical"):
        assert np.allclose(fit.mean, [0.2, 0.3, 0.5], atol=1e-6)


def _y_tree(mirror=False):
    """Root (0,0) → apex (0,1); continuation 0.8 long at 10° right of vertical, side 0.4 long at
    50° left. Counter-clockwise from 'back' (down): continuation at 170°, side at 230°."""
    s = -1.0 if mirror else 1.0
    c = np.array([s * 0.8 * math.sin(math.radians(10)), 1 + 0.8 * math.cos(math.radians(10))])
    d = np.array([-s * 0.4 * math.sin(math.radians(50)), 1 + 0.4 * math.cos(math.radians(50))])
    xz = np.array([[0, 0], [0, 1], d, c])          # side child first: order must not matter
    return np.array([-1, 0, 1, 1]), np.stack([xz[:, 0], np.zeros(4), xz[:, 1]], 1)


@pytest.mark.parametrize("mirror", [False, True])
def test_bifurcation_features_hand_case(mirror):
    parents, pos = _y_tree(mirror)
    f = features.bifurcation_features(parents, pos)
    assert list(f.apex) == [1] and list(f.leaves[0]) == [3, 2]           # continuation first
    assert np.allclose(f.angles[0], np.array([170, 60, 130]) / 360)       # θ / 2π
    assert np.allclose(f.lengths[0], np.array([1.0, 0.8, 0.4]) / 2.2)
    assert bool(f.mirrored[0]) == mirror


def test_spectral_features_hand_case():
    """One node rotating A sin(2π f t) about x at an exact bin: all energy in that bin, rms A/√2,
    u/v round-trip through the shift."""
    F, fps, A = 200, 20.0, 0.05
    t = np.arange(F) / fps
    rot = np.zeros((F, 2, 3))
    rot[:, 1, 0] = A * np.sin(2 * np.pi * 1.5 * t)            # bin 15 (1.5 Hz)
    sf = features.spectral_features(np.array([-1, 0]), rot, fps)[0]
    assert features.n_kept_bins(F) == 20 and len(sf.freqs_hz) == 20
    assert sf.freqs_hz[np.argmax(sf.energy[0])] == pytest.approx(1.5)
    assert sf.energy[0].max() == pytest.approx(1.0)
    assert sf.rms[0] == pytest.approx(A / math.sqrt(2), rel=1e-9)
    assert sf.u[0, 14] == pytest.approx(1.0)                  # aligned: all of it real positive
    z = features.shift_tuple(sf.u)
    assert np.allclose(z.sum(1), 1) and np.all(z >= 0)
    assert np.allclose(features.unshift_tuple(z), sf.u)


def test_node_rotations_recover_a_known_bend():
    """Rotating a 2-bone chain's top bone by 0.1 rad about x gives that local rotation."""
    parents = np.array([-1, 0, 1])
    rest = np.array([[0, 0, 0], [0, 0, 1.0], [0, 0, 2.0]])
    moved = rest.copy()
    moved[2] = [0, -math.sin(0.1), 1 + math.cos(0.1)]
    rot = features.node_rotations(parents, np.stack([rest, moved]))
    assert np.allclose(rot[1, 2], [0.1, 0, 0], atol=1e-9) and np.allclose(rot[1, 1], 0, atol=1e-12)


def test_fit_species_on_reconstruction_and_json_round_trip(tmp_path):
    tree = source_tree("broad")
    m = source_model("broad")
    f = features.bifurcation_features(tree.parents, tree.nodes3d[0])
    print(f"broad: {len(f.apex)} bifurcations, angle α {m.angles.round(2)}, length α {m.lengths.round(2)}, "
          f"peaks {[p.tolist() for p in (mm.peaks_hz() for mm in m.motion)]}")
    assert m.n_bifurcations == len(f.apex) >= 20
    assert np.abs(m.angles / m.angles.sum() - f.angles.mean(0)).max() < 0.03
    assert len(m.motion) == 3 and all(len(a.energy) == features.n_kept_bins(tree.n_frames) for a in m.motion)
    assert not m.fallbacks
    path = tmp_path / "broad.json"
    species.save_species(path, m)
    text = path.read_text()
    assert '"format": "tree_from_video.species"' in text and '"version": 1' in text
    back = species.load_species(path)
    assert back.to_json() == m.to_json()
    assert m.sway_excursion > 0 and back.sway_excursion == pytest.approx(m.sway_excursion, abs=1e-6)
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".tmp")]


def test_load_species_errors(tmp_path):
    good = source_model("broad").to_json()
    cases = {"missing": None, "not json": "{nope", "foreign": json.dumps({"format": "x"}),
             "newer": json.dumps({**good, "version": species.VERSION + 1}),
             "damaged": json.dumps({**good, "shape": {**good["shape"], "angle_alpha": [1, -2, 3]}}),
             "incomplete": json.dumps({k: v for k, v in good.items() if k != "motion"})}
    for name, content in cases.items():
        path = tmp_path / f"{name.replace(' ', '_')}.json"
        if content is not None:
            path.write_text(content)
        with pytest.raises(InputError) as exc:
            species.load_species(path)
        print(name, "→", exc.value)
        assert str(path) in str(exc.value)


def test_species_library_ships_the_samples():
    lib = species.species_library()
    assert {"broad", "sparse", "conifer", "palm"} <= set(lib)
    for name, path in lib.items():
        m = species.load_species(path)
        assert m.name == name and m.conifer == (name == "conifer")
        assert m.form == {"conifer": "conifer", "palm": "palm"}.get(name, "broadleaf")
        assert m.sway_excursion is None or m.sway_excursion > 0      # fitted before it was measured: None
        # a palm: one long trunk and a crown of a few fronds (forks only where binarized at its top)
        assert 0 < m.trunk_frac < 1 and m.n_bifurcations >= (5 if name == "palm" else 10)
        assert (m.palm is not None and m.palm["fronds"] >= 5) == (name == "palm")


def test_fit_species_rejects_unusable_trees():
    chain = Tree3D(np.array([-1, 0, 1]), np.zeros((20, 3, 3), np.float32) + [[0, 0, 0], [0, 0, 1], [0, 0, 2]],
                   np.ones(3, np.float32), np.zeros(3, np.int32), 24.0)
    with pytest.raises(InputError, match="no bifurcation"):
        species.fit_species(chain, "chain")
