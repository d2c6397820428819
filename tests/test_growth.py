"""Generated trees (paper §5.3): inside Ω', feature statistics like the model, determinism, motion
frequencies, wind and audio, Tree3D conventions, speed."""

import dataclasses

import cv2
import numpy as np
import pytest
import report
from scipy.io import wavfile

from tree_from_video.core import bones
from tree_from_video.core.detail.twigs import without_twigs
from tree_from_video.core.envelope import envelope_from_meta
from tree_from_video.core.errors import Cancelled, InputError
from tree_from_video.core.generate import (
    dirichlet,
    envelopes,
    features,
    growth,
    species,
    sway,
    wind,
)
from tree_from_video.core.topology import branching_level
from tree_from_video.core.tree3d import pipe_radii

from generation_data import source_model, source_tree

pytestmark = [pytest.mark.bpy53]


@pytest.fixture(scope="module")
def model():
    return source_model("broad")


def _inside_2d(poly: np.ndarray, pts: np.ndarray, tol: float) -> np.ndarray:
    c = poly.astype(np.float32).reshape(-1, 1, 2)
    return np.array([cv2.pointPolygonTest(c, (float(x), float(z)), True) >= -tol for x, z in pts])


ENVELOPES = ["source", "triangle", "circle", "pentagon", "heart"]


@pytest.mark.parametrize("shape", ENVELOPES)
def test_all_nodes_inside_envelope(model, shape):
    env = envelope_from_meta(source_tree("broad").meta) if shape == "source" else envelopes.topiary(shape, 8.0)
    poly = envelopes.envelope_polygon(env)
    H = float(np.max(env.z))
    rates, rates_moving = [], []
    for seed in range(3):
        still = growth.grow_tree(model, env, growth.GrowParams(seed=seed, wind=0.0, n_frames=2))
        rest = still.nodes3d[0].astype(float)
        cell = H / envelopes.RASTER_ROWS             # growth tests containment on a raster of Ω'
        in2d = _inside_2d(poly, rest[:, [0, 2]], cell)
        in3d = env.contains(rest, tol=cell)
        rates.append(min(in2d.mean(), in3d.mean()))
        moving = growth.grow_tree(model, env, growth.GrowParams(seed=seed, n_frames=60))
        P = moving.nodes3d.reshape(-1, 3).astype(float)
        rates_moving.append(_inside_2d(poly, P[::7, [0, 2]], 0.02 * H).mean())
        assert still.n_nodes >= 100
    print(f"{shape}: inside rate at rest {np.round(rates, 4)}, while swaying (2% slack) {np.round(rates_moving, 4)}")
    assert min(rates) == 1.0
    assert min(rates_moving) >= 0.99


def _features(model, env, seeds, **kw):
    """The bifurcations the growth made (twigs, copies of them, left out: the species is fitted
    without them)."""
    A, L = [], []
    for seed in seeds:
        t = without_twigs(growth.grow_tree(model, env, growth.GrowParams(seed=seed, wind=0.0, n_frames=2, **kw)))
        f = features.bifurcation_features(t.parents, t.nodes3d[0])
        A.append(f.angles)
        L.append(f.lengths)
    return np.concatenate(A), np.concatenate(L)


def test_feature_distributions_match_the_model(model):
    """50 trees: mean and spread of ⟨θ⟩ and ⟨L⟩ close to the model's Dirichlets, and closer to
    them than to another species' (sparse: a shorter side branch, a narrower fork)."""
    env = envelope_from_meta(source_tree("broad").meta)
    A, L = _features(model, env, range(50))
    rng = np.random.default_rng(0)
    MA, ML = rng.dirichlet(model.angles, 20000), rng.dirichlet(model.lengths, 20000)
    dA, dL = np.abs(A.mean(0) - MA.mean(0)), np.abs(L.mean(0) - ML.mean(0))
    rA, rL = A.std(0) / MA.std(0), L.std(0) / ML.std(0)
    print(f"{len(A)} bifurcations in 50 trees\n angles gen {A.mean(0).round(3)}±{A.std(0).round(3)} "
          f"model {MA.mean(0).round(3)}±{MA.std(0).round(3)}\n lengths gen {L.mean(0).round(3)}±{L.std(0).round(3)} "
          f"model {ML.mean(0).round(3)}±{ML.std(0).round(3)}")
    assert len(A) >= 1500
    # the generator's turns (a fork rotated to fit the envelope) pull the first angle share toward
    # ~0.51 whatever the model says: 0.017 off for a model at 0.495, 0.036 since the broad model's
    # skeleton also traces frame 1 (its share 0.478)
    assert dA.max() <= 0.045 and dL.max() <= 0.07
    assert np.all((rA > 0.75) & (rA < 1.4)) and np.all((rL > 0.75) & (rL < 1.4))
    # the Dirichlet log-likelihood of the generated features is higher under the own model
    other = species.load_species(species.species_library()["sparse"])
    mlA, mlL = np.log(np.maximum(A, 1e-12)).mean(0), np.log(np.maximum(L, 1e-12)).mean(0)
    own = dirichlet.dirichlet_loglik(model.angles, mlA) + dirichlet.dirichlet_loglik(model.lengths, mlL)
    alt = dirichlet.dirichlet_loglik(other.angles, mlA) + dirichlet.dirichlet_loglik(other.lengths, mlL)
    print(f" mean log-likelihood per bifurcation: own model {own:.3f}, sparse model {alt:.3f}")
    assert own > alt


def test_same_seed_same_tree_distinct_seeds_distinct_trees(model):
    env = envelopes.topiary("circle", 6.0)
    p = growth.GrowParams(seed=11, n_frames=30)
    a, b = growth.grow_tree(model, env, p), growth.grow_tree(model, env, p)
    assert np.array_equal(a.parents, b.parents) and np.array_equal(a.nodes3d, b.nodes3d)
    others = [growth.grow_tree(model, env, growth.GrowParams(seed=s, n_frames=30)) for s in (12, 13)]
    for o in others:
        same_topology = np.array_equal(o.parents, a.parents)
        assert not same_topology or not np.allclose(o.nodes3d[0], a.nodes3d[0], atol=1e-3)


def test_tree3d_conventions(model):
    env = envelopes.topiary("pentagon", 7.0, 5.0)
    twigged = growth.grow_tree(model, env, growth.GrowParams(seed=5, n_frames=40, node_budget=150))
    for t in (twigged, without_twigs(twigged)):
        assert t.parents[0] == -1 and np.count_nonzero(t.parents < 0) == 1
        assert np.all(t.parents[1:] < np.arange(1, t.n_nodes))          # parents first
        assert np.allclose(t.nodes3d[:, 0], 0.0)
        assert t.nodes3d.dtype == np.float32 and t.nodes3d.shape == (40, t.n_nodes, 3)
        bones.check_positions(t.parents, t.nodes3d)                         # no zero-length bone
        e = t.edges()
        L = np.linalg.norm(t.nodes3d[:, e[:, 1]] - t.nodes3d[:, e[:, 0]], axis=2)
        assert np.abs(L - L[:1]).max() < 1e-4                               # rotations keep lengths
    # the budget counts the grown branches; the twigs (two generations by default) come on top
    assert 100 <= t.n_nodes <= 150 and twigged.meta["twigs"]["depth"] == 2
    assert twigged.meta["twigs"]["first_node"] == t.n_nodes < twigged.n_nodes
    assert np.array_equal(t.level, branching_level(t.parents))
    tips = np.setdiff1d(np.arange(t.n_nodes), t.parents)
    assert np.allclose(t.radius[tips], t.radius[tips[0]])
    assert twigged.radius[t.n_nodes:].max() < t.radius[tips[0]]          # twigs finer than the tips
    H = t.meta["height_px"] * t.meta["metres_per_px"]
    np.testing.assert_allclose(t.radius, growth.species_radii(t.parents, H, model.widths), rtol=1e-5)
    assert t.radius[0] == pytest.approx(model.widths[0] * H, rel=1e-4)     # the source's trunk share
    assert t.meta["species"] == "broad" and t.meta["seed"] == 5 and t.meta["generated"]
    assert envelope_from_meta(t.meta) is not None and "polygon" in t.meta["envelope"]
    assert np.max(t.meta["envelope"]["z"]) == pytest.approx(7.0, rel=0.02)


def test_dominant_frequencies_match_the_source(model):
    src = source_tree("broad")
    bin_hz = src.fps / src.n_frames
    want = features.dominant_frequencies(src)
    env = envelope_from_meta(src.meta)
    for seed in range(3):
        t = without_twigs(growth.grow_tree(model, env, growth.GrowParams(seed=seed, n_frames=src.n_frames,
                                                                         fps=src.fps)))
        got = features.dominant_frequencies(t)
        print(f"seed {seed}: source peaks {want.round(3).tolist()} Hz, generated {got.round(3).tolist()} Hz "
              f"(bin {bin_hz:.3f} Hz)")
        assert np.all(np.abs(got - want) <= bin_hz + 1e-9)
        _, es = features.energy_spectrum(src)
        _, eg = features.energy_spectrum(t)
        assert np.abs(es - eg).sum(1).max() < 0.25       # L1 distance of the mean energy spectra


def _rotation_rms(tree):
    rot = features.node_rotations(tree.parents, tree.nodes3d.astype(float))
    return float(np.sqrt(np.mean(rot[:, 1:] ** 2)))


def test_wind_scales_the_amplitude(model):
    env = envelopes.topiary("circle", 6.0)
    # wind 0.5 -> 1: the linear range. Since tracks are re-detected the broad model keeps its sway
    # (amplitude ratio ~1.0 instead of ~0.8), and at wind 2 the generator's bounds (envelope depth,
    # rotation limits) saturate it: x1.86 measured for 1 -> 2, x2.000 for 0.5 -> 1
    t1 = growth.grow_tree(model, env, growth.GrowParams(seed=3, n_frames=120, wind=0.5))
    t2 = growth.grow_tree(model, env, growth.GrowParams(seed=3, n_frames=120, wind=1.0))
    t0 = growth.grow_tree(model, env, growth.GrowParams(seed=3, n_frames=120, wind=0.0))
    r_rot = _rotation_rms(t2) / _rotation_rms(t1)
    d1 = np.linalg.norm(t1.nodes3d - t0.nodes3d, axis=2).mean()
    d2 = np.linalg.norm(t2.nodes3d - t0.nodes3d, axis=2).mean()
    print(f"wind 0.5 -> 1: rotation RMS ×{r_rot:.4f}, mean node displacement ×{d2 / d1:.4f} ({d1:.4f} → {d2:.4f} m)")
    assert np.allclose(t0.nodes3d, t0.nodes3d[:1])                   # no wind: still
    assert r_rot == pytest.approx(2.0, rel=0.02)
    assert d2 / d1 == pytest.approx(2.0, rel=0.05)


def _gusty_wav(path, rate=8000, seconds=12.0, dtype="int16", stereo=True):
    t = np.arange(int(rate * seconds)) / rate
    env = 0.25 + 0.75 * (0.5 + 0.5 * np.sin(2 * np.pi * t / 5.0 - 1.0)) ** 2   # gusts every 5 s
    noise = np.random.default_rng(0).standard_normal(len(t))
    x = 0.4 * env * noise / 3
    if dtype == "int16":
        data = np.clip(x * 32767, -32768, 32767).astype(np.int16)
    elif dtype == "int32":
        data = np.clip(x * 2147483647, -2 ** 31, 2 ** 31 - 1).astype(np.int32)
    else:
        data = x.astype(np.float32)
    if stereo:
        data = np.stack([data, data], 1)
    wavfile.write(str(path), rate, data)
    return t, env


def test_audio_envelope_formats_and_errors(tmp_path):
    fps, F = 24.0, 240
    ref = None
    for dtype, stereo in (("int16", True), ("int32", False), ("float32", True)):
        p = tmp_path / f"w_{dtype}.wav"
        t, env = _gusty_wav(p, dtype=dtype, stereo=stereo)
        a = wind.audio_envelope(p, fps, F)
        assert a.shape == (F,) and a.mean() == pytest.approx(1.0)
        truth = np.interp(np.arange(F) / fps, t, env)
        c = np.corrcoef(a, truth)[0, 1]
        print(f"{dtype} {'stereo' if stereo else 'mono'}: correlation with the true envelope {c:.3f}")
        assert c >= 0.95
        if ref is not None:
            assert np.allclose(a, ref, atol=0.02)
        ref = a
    (tmp_path / "text.wav").write_text("not audio")
    wavfile.write(str(tmp_path / "empty.wav"), 8000, np.zeros(0, np.int16))
    wavfile.write(str(tmp_path / "silent.wav"), 8000, np.zeros(8000, np.int16))
    for name in ("missing.wav", "text.wav", "empty.wav", "silent.wav"):
        with pytest.raises(InputError) as exc:
            wind.audio_envelope(tmp_path / name, fps, F)
        print(name, "→", exc.value)


def test_audio_drives_the_sway(model, tmp_path):
    fps, F = 24.0, 240
    p = tmp_path / "gusts.wav"
    _gusty_wav(p)
    env = envelopes.topiary("circle", 6.0)
    a = wind.audio_envelope(p, fps, F)
    t = growth.grow_tree(model, env, growth.GrowParams(seed=4, n_frames=F, fps=fps), audio=str(p))
    rot = features.node_rotations(t.parents, t.nodes3d.astype(float))[:, 1:]
    amp = np.sqrt(np.mean(rot ** 2, axis=(1, 2)))                   # instantaneous amplitude
    k = np.exp(-0.5 * (np.arange(-12, 13) / 6.0) ** 2)
    amp_s = np.convolve(np.pad(amp, 12, mode="edge"), k / k.sum(), mode="valid")
    c = np.corrcoef(amp_s, a)[0, 1]
    print(f"audio drive: correlation of the sway amplitude with the audio envelope {c:.3f}")
    assert c >= 0.8
    assert t.meta["audio"] == str(p)


def test_envelopes_from_image_and_polygon(tmp_path):
    img = np.full((300, 200), 255, np.uint8)
    cv2.circle(img, (100, 120), 80, 0, -1)
    cv2.rectangle(img, (95, 180), (105, 290), 0, -1)                 # a lollipop: disk on a stem
    cv2.imwrite(str(tmp_path / "lolli.png"), img)
    e = envelopes.envelope_from_image(tmp_path / "lolli.png", 9.0)
    assert e.z.max() == pytest.approx(9.0, rel=0.02) and e.z.min() == pytest.approx(0.0, abs=0.05)
    assert 2 * e.radius.max() == pytest.approx(9.0 * 161 / 251, rel=0.05)
    rgba = np.zeros((100, 100, 4), np.uint8)
    cv2.rectangle(rgba, (30, 10), (70, 90), (255, 255, 255, 255), -1)
    cv2.imwrite(str(tmp_path / "box.png"), rgba)
    b = envelopes.envelope_from_image(tmp_path / "box.png", 4.0)
    assert 2 * b.radius.max() == pytest.approx(4.0 * 41 / 81, rel=0.05)
    cv2.imwrite(str(tmp_path / "blank.png"), np.full((50, 50), 200, np.uint8))
    (tmp_path / "bad.png").write_bytes(b"\x89PNG broken")
    for name in ("blank.png", "bad.png", "none.png"):
        with pytest.raises(InputError):
            envelopes.envelope_from_image(tmp_path / name, 5.0)
    poly = np.array([[10, 5], [14, 5], [14, 9], [12, 11], [10, 9]], float)
    pe = envelopes.envelope_from_polygon(poly)
    assert np.allclose(pe.offset, [12, 5], atol=0.05) and pe.z.max() == pytest.approx(6.0, rel=0.02)
    with pytest.raises(InputError):
        envelopes.envelope_from_polygon(np.array([[0, 0], [1, 1], [2, 2]]))
    with pytest.raises(InputError):
        envelopes.topiary("star", 5.0)


def test_cancel_and_bad_parameters(model):
    env = envelopes.topiary("heart", 6.0)
    calls = []

    def stop_soon(stage, frac):
        calls.append(stage)
        return len(calls) < 3
    with pytest.raises(Cancelled):
        growth.grow_tree(model, env, growth.GrowParams(seed=1), progress=stop_soon)
    for bad in (dict(node_budget=2), dict(n_frames=0), dict(wind=-1.0), dict(height_m=0.0)):
        with pytest.raises(InputError):
            growth.grow_tree(model, env, growth.GrowParams(**bad))




def test_generated_trees_carry_the_species_foliage():
    """A species fitted from a leafy reconstruction keeps its foliage (colour, cluster size, clusters
    per twig node); a generated tree gets clusters on its thin branches in that colour, and leaf
    density trades clusters for size (paper §5). (Without the source's fill: with it, the count
    then follows the crown's cover, test_generated_crowns_fill_their_envelope_as_the_source.)"""
    model = species.load_species(species.species_library()["broad"])
    assert model.leaves is not None and "fill" in model.leaves
    model = dataclasses.replace(model, leaves={k: v for k, v in model.leaves.items() if k != "fill"})
    env = envelopes.topiary("circle", 6.0)
    full = growth.grow_tree(model, env, growth.GrowParams(seed=4, n_frames=48))
    half = growth.grow_tree(model, env, growth.GrowParams(seed=4, n_frames=48, leaf_density=0.5))
    a, b = full.leaves, half.leaves
    r = without_twigs(full).radius                  # per thin branch node, counted without twigs as
    thin = int(np.sum((r < 0.3 * r.max()) & (np.arange(len(r)) > 0)))          # in the species
    on = a.node[np.argsort(a.node)]
    assert np.any(on >= len(r)) and np.all(full.radius[on] < 0.3 * r.max())  # ... hung on twigs too
    print(f"\n{a.count} clusters on {thin} thin nodes (species {model.leaves['per_node']:.2f} per node); "
          f"density 0.5: {b.count}, radius {a.radius:.3f} → {b.radius:.3f} m")
    assert a.count == pytest.approx(model.leaves["per_node"] * thin, abs=1)
    assert b.count == pytest.approx(0.5 * a.count, rel=0.05)
    assert b.radius / a.radius == pytest.approx(np.sqrt(2), rel=1e-6)
    np.testing.assert_allclose(np.median(a.colour, axis=0), model.leaves["colour"], atol=0.03)
    assert a.flutter.shape == (48, a.count) and np.isfinite(a.flutter).all()
    bare = growth.grow_tree(model, env, growth.GrowParams(seed=4, n_frames=48, leaf_density=0.0))
    assert bare.leaves is None


def test_no_seed_leaves_a_bare_pole():
    """Every seed grows a real crown: a first fork that does not fit is resampled, not the end of
    the tree (before the fix, seeds 44 and 47 of 60 stopped at 9 nodes in a circle)."""
    model = species.load_species(species.species_library()["broad"])
    env = envelopes.topiary("circle", 8.0)
    sizes = [growth.grow_tree(model, env, growth.GrowParams(seed=s, node_budget=120, n_frames=8, leaf_density=0)).n_nodes
             for s in range(60)]
    print(f"\nnodes over 60 seeds: min {min(sizes)}, median {int(np.median(sizes))}")
    assert min(sizes) >= 60


def test_a_sway_that_would_leave_the_envelope_is_scaled_down_to_stay_in_it(model):
    env = envelopes.topiary("circle", 6.0)
    region = envelopes.region_of(env)
    # a 3 m pole in the middle of a 6 m circle (radius 3 m): bent by 1.5 rad about y it leaves the circle
    parents = np.array([-1, 0, 1])
    rest = np.array([[0.0, 0.0, 1.5], [0.0, 0.0, 3.0], [0.0, 0.0, 4.5]])
    F = 40
    rot = np.zeros((F, 3, 3))
    rot[:, 1, 1] = 1.5 * np.sin(np.linspace(0, 2 * np.pi, F))
    nodes, factor = growth.contain_sway(parents, rest, rot, region)
    assert 0.0 < factor < 1.0
    assert np.allclose(nodes, sway.forward_kinematics(parents, rest, rot * factor))
    poly = envelopes.envelope_polygon(env)
    H = 4.5
    inside = _inside_2d(poly, nodes.reshape(-1, 3)[:, [0, 2]], growth.SWAY_SLACK * H + region.cell)
    assert inside.mean() >= 1 - growth.SWAY_OUTSIDE
    # a gentle sway is untouched
    calm, one = growth.contain_sway(parents, rest, rot * 0.05, region)
    assert one == 1.0 and np.allclose(calm, sway.forward_kinematics(parents, rest, rot * 0.05))
    # and grown trees: the factor is recorded, the same at every wind (wind 2 is twice wind 1)
    t1 = growth.grow_tree(model, env, growth.GrowParams(seed=1, n_frames=30, wind=1.0))
    t2 = growth.grow_tree(model, env, growth.GrowParams(seed=1, n_frames=30, wind=2.0))
    assert t1.meta["sway_scale"] == t2.meta["sway_scale"]


def test_sway_excursion_by_hand():
    # two nodes: one still, one swinging ±0.3 m about its mean on x: the farthest it gets is 0.3 m
    X = np.zeros((4, 2, 3))
    X[:, 1, 0] = [0.3, -0.3, 0.3, -0.3]
    assert species.sway_excursion(X, 3.0) == pytest.approx(np.percentile([0.0, 0.3], 95) / 3.0)
    assert species.sway_excursion(X[:1], 3.0) == 0.0


def test_generated_trees_sway_as_far_as_their_source(model):
    """At wind 1 a generated tree's nodes sway as far (share of the height) as the source's did,
    whatever the spectra's per-bone amplitudes add up to along its chains; a species fitted before
    the excursion was measured (None) is left as sampled. A tree grows to fill its envelope, so the
    containment may still scale its sway down a little (``sway_scale``; since it is contained in 3D
    with at most 2 % of the nodes out in any frame, 0.875 for seed 0 under bpy 5.3's OpenCV): the
    excursion is then that share of the source's."""
    src = source_tree("broad")
    assert model.sway_excursion == pytest.approx(
        species.sway_excursion(src.nodes3d.astype(float), float(np.ptp(src.nodes3d[0, :, 2]))))
    env = envelopes.topiary("circle", 12.0)           # roomy: the envelope scales nothing down
    for seed in (0, 1, 2):
        t = without_twigs(growth.grow_tree(model, env, growth.GrowParams(seed=seed, n_frames=60, leaf_density=0)))
        k = t.meta["sway_scale"]
        assert 0.8 <= k <= 1.0, k
        X = t.nodes3d.astype(float)
        got = species.sway_excursion(X, float(X[0, :, 2].max()))
        print(f"seed {seed}: excursion {got:.4f} of the height, source {model.sway_excursion:.4f}, containment {k:.3f}")
        assert got == pytest.approx(k * model.sway_excursion, rel=0.05)
    assert growth.match_excursion(t.parents, X[0], np.zeros((5,) + X[0].shape), 0.05) == 1.0    # no sway: 1
    import dataclasses
    raw = dataclasses.replace(model, sway_excursion=None)
    assert growth.match_excursion(t.parents, X[0], np.ones((5,) + X[0].shape), None) == 1.0
    t_raw = without_twigs(growth.grow_tree(raw, env, growth.GrowParams(seed=2, n_frames=60, leaf_density=0)))
    assert not np.allclose(t_raw.nodes3d, t.nodes3d)                    # as sampled: another sway


def test_no_sampled_bone_sways_more_than_the_sources_most_swaying_bone(model):
    """The per-bone rms is log-normal in depth; its tail along a steep depth slope reached 0.87 rad
    (under bpy 5.3's OpenCV) where the source's bones reach 0.085: clipped to the source's largest
    per axis, so the sway's energy is not held by a handful of flailing twigs (the audio's gusts
    then show in the tree's amplitude: correlation 0.45 -> 0.92 there)."""
    caps = np.array([m.rms_max for m in model.motion])
    src = source_tree("broad")
    rot_src = features.node_rotations(src.parents, src.nodes3d.astype(float))
    assert caps == pytest.approx([sf.rms.max() for sf in features.spectral_features(src.parents, rot_src, src.fps)])
    env = envelopes.topiary("circle", 6.0)
    for seed in range(4):
        g = growth.grow_tree(model, env, growth.GrowParams(seed=seed, n_frames=8, leaf_density=0))
        rot = sway.sample_rotations(model, g.parents, g.nodes3d[0].astype(float), 240, 24.0, np.random.default_rng(seed))
        rms = np.sqrt((rot ** 2).mean(0).sum(-1))                    # (N,) radians
        assert rms.max() <= np.sqrt((caps ** 2).sum()) * 1.0001, (rms.max(), caps)


def test_species_radii_by_hand():
    """Pipe model fitted to the source's widths: 4 tips of 0.01 H under a trunk of 0.04 H need
    r_trunk = tip · n^(1/e), e = ln 4 / ln 4 = 1; kept at 1.5, then scaled to the trunk exactly.
    16 tips under a trunk 0.04 H with tips 0.01 H: e = ln 16 / ln 4 = 2 (no scaling needed)."""
    star = np.array([-1, 0, 1, 1, 1, 1])                       # root → fork → 4 tips
    r = growth.species_radii(star, 10.0, (0.04, 0.01))
    assert r[0] == pytest.approx(0.4) and r[1] == pytest.approx(0.4)
    assert r[2] == pytest.approx(0.1 * 0.4 / (0.1 * 4 ** (1 / 1.5)))
    fan = np.array([-1, 0] + [1] * 16)
    r = growth.species_radii(fan, 10.0, (0.04, 0.01))
    np.testing.assert_allclose(r, [0.4, 0.4] + [0.1] * 16, rtol=1e-5)
    np.testing.assert_allclose(growth.species_radii(fan, 10.0, None), pipe_radii(fan, 0.025), rtol=1e-6)


def test_generated_crowns_fill_their_envelope_as_the_source(model):
    """Issue 19 item 6: a generated crown, at the default node budget and twig depth, covers as
    much of its envelope's front view as the source's leaves cover of the source's envelope
    (within 10 %), in the source's own envelope and in another shape, for a dense (broad) and a
    nearly leafless (sparse) source; every cluster hangs within ``REACH`` cluster radii (front
    view) of the drawn branch or twig that carries it, and no cluster is blown up more than 10 %
    to get there; trunk and tip widths follow the source's (trunk within 10 %, median tip of the
    grown branches within 30 %). Before: 0.22–0.32 against broad's 0.59; then, with foliage
    hung on twigs that were not drawn, 0.584–0.593 with clusters up to 2.99 radii from any drawn
    branch and, for one seed, blown up 1.5×."""
    from tree_from_video.core.detail.grown_leaves import REACH, envelope_cover
    from tree_from_video.core.envelope import envelope_from_meta
    from tree_from_video.core.generate.species import branch_widths
    lines = [f"{'source':<8}{'envelope':<10}{'seed':>5}{'fill':>7}{'source':>8}{'reach':>7}{'grow':>6}"
             f"{'trunk r/H':>10}{'source':>8}{'tip r/H':>9}{'source':>8}"]
    for name in ("broad", "sparse"):
        src, m = source_tree(name), source_model(name)
        target = m.leaves["fill"]
        assert target == pytest.approx(envelope_cover(src.leaves, envelope_from_meta(src.meta)))
        for shape, env in (("own", envelope_from_meta(src.meta)), ("triangle", envelopes.topiary("triangle", 8.0))):
            for seed in (11, 12, 13):
                g = growth.grow_tree(m, env, growth.GrowParams(seed=seed, n_frames=12))
                lv = g.leaves
                fill = envelope_cover(lv, envelope_from_meta(g.meta))
                reach = float(np.linalg.norm((lv.pos - g.nodes3d[0][lv.node])[:, [0, 2]], axis=1).max() / lv.radius)
                grow = 1.0 if lv.scale is None else float(np.max(lv.scale))
                sk = without_twigs(g)
                trunk, tip = branch_widths(sk.parents, sk.radius, float(sk.nodes3d[0][:, 2].max()))
                lines.append(f"{name:<8}{shape:<10}{seed:>5}{fill:7.3f}{target:8.3f}{reach:7.2f}{grow:6.2f}"
                             f"{trunk:10.4f}{m.widths[0]:8.4f}{tip:9.4f}{m.widths[1]:8.4f}")
                assert fill == pytest.approx(target, rel=0.10), lines[-1]
                assert reach <= REACH + 1e-6 and grow <= 1.1, lines[-1]
                assert trunk == pytest.approx(m.widths[0], rel=0.10), lines[-1]
                assert tip == pytest.approx(m.widths[1], rel=0.30), lines[-1]
    report.add("Generated crowns' fill and widths vs the source (tests/test_growth.py)", lines)
