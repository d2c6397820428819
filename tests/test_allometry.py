"""Allometry per fork (issue 36 part 3, seed 001 §4.4; core/generate/allometry.py): the pipe
exponent and Holton's angle rule on hand-built forks, generated trees keeping the exponent their
radii were made with, and a reconstruction reporting its own."""
import numpy as np
import pytest

from tree_from_video.core.generate.allometry import allometry_report, fork_exponents, forks, holton_a1
from tree_from_video.core.generate.batch import load_species_spec
from tree_from_video.core.generate.envelopes import topiary
from tree_from_video.core.generate.growth import GrowParams, grow_tree


def y_fork(r0, r1, r2, a1_deg, a2_deg):
    """Root 0 → fork 1 (straight up) → children 2 and 3 at a1 right and a2 left of vertical."""
    a1, a2 = np.radians(a1_deg), np.radians(a2_deg)
    pos = np.array([[0, 0, 0], [0, 0, 1], [np.sin(a1), 0, 1 + np.cos(a1)], [-np.sin(a2), 0, 1 + np.cos(a2)]], float)
    return np.array([-1, 0, 1, 1]), pos, np.array([r0, r0, r1, r2])


@pytest.mark.parametrize("r1,r2,delta", [(0.8, 0.6, 2.0), (2 ** -0.5, 2 ** -0.5, 2.0),
                                          (0.9, (1 - 0.9 ** 3) ** (1 / 3), 3.0), (0.5, 0.5, 1.0)])
def test_pipe_exponent_by_hand(r1, r2, delta):
    # d^Δ = d1^Δ + d2^Δ with d = 2: the children chosen so the fork's Δ is known
    f = forks(*y_fork(1.0, r1, r2, 30, 30))
    assert len(f.node) == 1 and f.node[0] == 1 and f.d1[0] >= f.d2[0]
    assert abs(fork_exponents(f)[0] - delta) < 1e-6


def test_no_exponent_when_a_child_is_as_thick():
    f = forks(*y_fork(1.0, 1.0, 0.5, 10, 40))
    assert np.isnan(fork_exponents(f)[0])
    rep = allometry_report(*y_fork(1.0, 1.0, 0.5, 10, 40))
    assert rep["no_exponent"] == 1 and "pipe_exponent" not in rep


def test_holton_angles_by_hand():
    # equal children split the angle; d1 = 0.8, d2 = 0.6 (γ = 2): a1 = a · 0.36 / (0.64 + 0.36)
    assert np.isclose(holton_a1(np.radians(60.0), 1.6, 1.6), np.radians(30.0))
    assert np.isclose(np.degrees(holton_a1(np.radians(60.0), 1.6, 1.2)), 21.6)
    # a fork built to Holton's rule has no error; one built against it has the difference
    good = allometry_report(*y_fork(1.0, 0.8, 0.6, 21.6, 38.4))
    bad = allometry_report(*y_fork(1.0, 0.8, 0.6, 38.4, 21.6))
    assert good["holton_error_deg"] < 1e-6 and abs(bad["holton_error_deg"] - 16.8) < 1e-3
    assert abs(good["pipe_exponent"] - 2.0) < 1e-6 and good["leonardo_residual"] < 1e-9


@pytest.mark.parametrize("exponent", [2.0, 2.5])
def test_generated_trees_keep_their_exponent(exponent):
    model = load_species_spec("broad")[0]
    tree = grow_tree(model, topiary("circle", 10.0), GrowParams(seed=31, n_frames=4, node_budget=150, twig_depth=0,
                                                                leaf_density=0.0, pipe_exponent=exponent))
    rep = tree.meta["allometry"]
    print(f"exponent {exponent}: {rep}")
    assert rep["forks"] >= 10 and rep["no_exponent"] == 0
    assert abs(rep["pipe_exponent"] - exponent) < 0.02
    assert rep["pipe_exponent_iqr"][1] - rep["pipe_exponent_iqr"][0] < 0.05
    assert rep["species_mu_deg"] == round(model.mu_deg, 3)


def test_a_reconstruction_reports_its_forks():
    import os

    from tree_from_video.core import pipeline

    from samples import committed, plain_settings
    folder, s = committed("broad"), plain_settings()
    res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
    rep = pipeline.build_3d(res, s).meta["allometry"]
    print(rep)
    # the broad sample's measured radii: most forks near Leonardo's rule (Δ = 2), a few with a child
    # traced as thick as its father
    assert rep["forks"] >= 20 and 1.8 <= rep["pipe_exponent"] <= 2.6 and rep["no_exponent"] <= 0.2 * rep["forks"]
    assert rep["leonardo_residual"] < 0.1 and 0 < rep["holton_error_deg"] < 30
