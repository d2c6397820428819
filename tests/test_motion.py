"""3D motion (paper §4) against the synthetic trees' true motion, and the solvers' building blocks."""
import numpy as np
import pytest
import report
from conftest import BAR_VARIANTS

from tree_from_video.core import rotations
from tree_from_video.core.reconstruct import lift, motion, rotation_solve
from tree_from_video.core.tree3d import image_to_plane

from motion_metrics import motion_scores

pytestmark = [pytest.mark.slow]


@pytest.fixture(scope="session")
def solved(runs):
    """{variant: {"prob": scores, "det": scores, "motion": Motion}} for every bar variant + dense."""
    out = {}
    for v in BAR_VARIANTS + ("dense",):
        res = runs[v]["traced"]
        sk = res.skeleton
        L = lift.lift(sk, res.outline, lift.LiftParams(conifer=(v == "conifer")))
        base = sk.nodes2d[0, 0].astype(np.float64)
        tgt = image_to_plane(sk.nodes2d.astype(np.float64), base)[..., [0, 2]]
        entry = {}
        for key, solver in (("prob", "probabilistic"), ("det", "deterministic")):
            prm = motion.MotionParams(solver=solver).for_form(v == "conifer")
            m = motion.solve_motion(L.nodes, sk.parents, sk.level, tgt, prm)
            entry[key] = motion_scores(m.nodes.astype(np.float64), sk.parents, tgt, base, runs[v]["truth"])
            entry[key + "_motion"] = m
            entry[key + "_fit"] = motion.motion_fit(m.nodes, sk.parents, tgt, sk.confidence).summary()
        out[v] = entry
    lines = [f"{'variant':<9}{'solver':<7}{'reproj med':>11}{'max':>7}{'measured':>9}{'unmeas':>7}"
             f"{'dα95°':>7}{'truth':>7}{'dαmax°':>8}{'truth':>7}{'amp':>6}{'corr':>6}{'2D':>6}"]
    for v, e in out.items():
        for key in ("prob", "det"):
            s = e[key]
            f = e[key + "_fit"]
            lines.append(f"{v:<9}{key:<7}{100 * s['reproj_median']:10.2f}%{100 * s['reproj_max']:6.2f}%"
                         f"{100 * f['max']:8.2f}%{100 * f['unmeasured']:6.1f}%"
                         f"{s['angle95']:7.1f}{s['true_angle95']:7.1f}{s['angle_max']:8.1f}{s['true_angle_max']:7.1f}"
                         f"{s['tip_amplitude_ratio']:6.2f}{s['tip_corr']:6.2f}{s['tip_corr_2d']:6.2f}")
    report.add("3D motion vs truth (tests/test_motion.py)", lines)
    return out


@pytest.mark.parametrize("variant", BAR_VARIANTS + ("dense",))
def test_reprojection_and_lengths(solved, variant):
    """The 3D motion keeps to the measured 2D motion (issue 35): at every measured node-frame its
    projection lies within 3 % of the height of the tracked position (it was 6 %, and 9 % on
    sparse, while a chain node's whole displacement came from its chain's ends); at most 5 % of the
    node-frames unmeasured (low confidence, or tracked past the reach of the bones to an ancestor
    or descendant: ``motion.out_of_reach``); median ≤ 1 %; lengths exact."""
    s, fit = solved[variant]["prob"], solved[variant]["prob_fit"]
    assert fit["max"] <= motion.REPROJECTION_BOUND and fit["over"] == 0, fit
    assert fit["unmeasured"] <= 0.05 and s["reproj_median"] <= 0.01, (fit, s)
    assert s["length_change"] <= 0.01, s


@pytest.mark.parametrize("variant", BAR_VARIANTS)
def test_branch_angles_stay_close_to_the_truth(solved, variant):
    """Branches bend about as much as the true ones (95th percentile of the change of branch
    angles at least 0.6 of the truth's; 0.35–0.68 with the shape term's σ at 1.1°) and not more
    than 1.5×; the conifer at least 0.4 (its leader is kept straight)."""
    s = solved[variant]["prob"]
    assert s["angle95"] >= (0.4 if variant == "conifer" else 0.6) * s["true_angle95"], s
    assert s["angle95"] <= 1.5 * s["true_angle95"], s
    assert s["angle_max"] <= min(2 * s["true_angle_max"], 30.0), s


def test_probabilistic_beats_deterministic_without_going_stiff(solved):
    p, d = solved["hard"]["prob"], solved["hard"]["det"]
    print(f"hard: angle95 {p['angle95']:.1f}° vs deterministic {d['angle95']:.1f}°, "
          f"max {p['angle_max']:.1f}° vs {d['angle_max']:.1f}°")
    assert p["angle95"] < d["angle95"] and p["angle_max"] < d["angle_max"]
    for v in BAR_VARIANTS:
        assert 0.7 <= solved[v]["prob"]["tip_amplitude_ratio"] <= 1.3, (v, solved[v]["prob"])


@pytest.mark.parametrize("variant", BAR_VARIANTS)
def test_tip_motion_correlates_like_the_2d_skeleton(solved, variant):
    """3D tips' x motion correlates with the truth nearly as well as the 2D skeleton's (within
    0.03; gentle, whose branches turn by 0.4°, within 0.08: measured 0.87 vs 0.93 in 2D, and 0.94
    with a trace that leaves out frame 1's background cost)."""
    s = solved[variant]["prob"]
    assert s["tip_corr"] >= s["tip_corr_2d"] - (0.08 if variant == "gentle" else 0.03), s


def test_accumulated_rotation_never_exceeds_delta(solved):
    delta = motion.MotionParams().max_total
    for v, e in solved.items():
        assert np.linalg.norm(e["prob_motion"].accumulated, axis=-1).max() <= delta + 1e-6, v


# --- building blocks, by hand ---------------------------------------------------------------

def test_rodrigues_quarter_turn():
    R = rotations.rodrigues(np.array([[0.0, 0.0, np.pi / 2]]))[0]
    assert R @ np.array([1.0, 0, 0]) == pytest.approx([0, 1, 0], abs=1e-12)


def test_deterministic_sphere_meets_line_of_sight():
    # parent at the origin, branch length 5 along z; target (x, z) = (3, 4): the line of sight
    # x = 3, z = 4 meets the sphere |X| = 5 at depth 0 (a single point: 9 + 16 = 25)
    rest = np.array([[0, 0, 0], [0, 0, 5.0]])
    parents = np.array([-1, 0])
    tg = np.array([[[0, 0], [0, 5]], [[0, 0], [3, 4]]], float)
    m = motion.solve_motion(rest, parents, np.zeros(2, int), tg, motion.MotionParams(solver="deterministic"))
    assert m.nodes[1, 1] == pytest.approx([3, 0, 4], abs=1e-5)
    # target (x, z) = (0, 3): depth ±4, the one nearer the previous depth (0 → either; then keeps sign)
    tg = np.array([[[0, 0], [0, 5]], [[0, 0], [0, 3]], [[0, 0], [0, 3.5]]], float)
    m = motion.solve_motion(rest, parents, np.zeros(2, int), tg, motion.MotionParams(solver="deterministic"))
    assert abs(m.nodes[1, 1, 1]) == pytest.approx(4.0, abs=1e-5)
    assert np.sign(m.nodes[2, 1, 1]) == np.sign(m.nodes[1, 1, 1])
    assert np.linalg.norm(m.nodes[2, 1]) == pytest.approx(5.0, abs=1e-5)
    # an unreachable target (x = 10) is pulled toward the previous projection until reachable
    tg = np.array([[[0, 0], [0, 5]], [[0, 0], [10, 5]]], float)
    m = motion.solve_motion(rest, parents, np.zeros(2, int), tg, motion.MotionParams(solver="deterministic"))
    assert np.linalg.norm(m.nodes[1, 1]) == pytest.approx(5.0, abs=1e-5)
    assert m.nodes[1, 1, 1] == pytest.approx(0.0, abs=1e-5)   # on the sphere's silhouette


def test_out_of_reach_by_hand():
    """A straight chain of three 10 px bones (root 0 → 1 → 2 → 3), tolerance 0.5 px an edge.
    Frame 1: every edge tracked 0.4 px long: each within its 0.5, the paths within 1.0 and 1.5
    px: none. Frame 2: the chain bent, every chord shorter than its bones: none. Frame 3: the
    middle edge 1.2 px long and the tip following node 2: the edge marks both its ends (1, 2),
    and the tip lies 1.2 px past the 20 px of bones to node 1 (allowed 1.0): the tip too, the root
    not (1.2 past 30, allowed 1.5 to the tip; 1.2 past 20 to node 2, allowed 1.0: node 2, already
    marked). Frame 4: the tip's edge alone 0.6 px long: both its ends (2, 3) and nothing above."""
    rest = np.array([[0, 0, 0], [0, 0, 10], [0, 0, 20], [0, 0, 30]], float)
    parents = np.array([-1, 0, 1, 2])
    frames = np.array([[[0, 0], [0, 10.4], [0, 20.8], [0, 31.2]],
                       [[0, 0], [0, 10], [7.07, 17.07], [14.14, 24.14]],
                       [[0, 0], [0, 10], [0, 21.2], [0, 31.2]],
                       [[0, 0], [0, 10], [0, 20], [0, 30.6]]])
    bad = motion.out_of_reach(rest, parents, frames, 0.5)
    assert bad.tolist() == [[False] * 4, [False] * 4, [False, True, True, True], [False, False, True, True]]


def test_chain_targets_follow_their_ends_by_arc_length():
    # root 0 → 1 → 2 → 3 (tip): nodes 1, 2 are chain nodes at 1/3 and 2/3 of the arc
    parents = np.array([-1, 0, 1, 2])
    t0 = np.array([[0, 0], [0, 1], [0, 2], [0, 3]], float)
    t1 = t0 + np.array([[0, 0], [5, 5], [-5, 5], [3, 0]])   # chain nodes jitter, tip moves 3 in x
    out = motion.smooth_chain_targets(np.stack([t0, t1]), parents)
    # along the interpolated chain (0,0)→(1,1)→(2,2)→(3,3) the nodes sit at (1, 1) and (2, 2); across
    # it, normal n = (−1, 1)/√2, each keeps its own displacement: node 1 measured (5, 6), (4, 5)·n =
    # 1/√2 → (1, 1) + (−0.5, 0.5); node 2 measured (−5, 7), (−7, 5)·n = 12/√2 → (2, 2) + (−6, 6)
    assert out[1, 1] == pytest.approx([0.5, 1.5]) and out[1, 2] == pytest.approx([-4, 8])
    straight = t0 + np.array([[0, 0], [0, 5], [0, -1], [0, 3]])     # jitter only along the chain
    out = motion.smooth_chain_targets(np.stack([t0, straight]), parents)
    assert out[1, 1] == pytest.approx([0, 2]) and out[1, 2] == pytest.approx([0, 4])
    assert out[1, 3] == pytest.approx([0, 6]) and out[1, 0] == pytest.approx([0, 0])   # the ends are their own


def _fork():
    """A small tree: a trunk 0 → 1, a branch 1 → 2 → 3 and a side branch 1 → 4, in 3D (px)."""
    rest = np.array([[0, 0, 0], [0.5, 0, 8.0], [5.0, 1.0, 14.0], [8.0, 2.0, 19.0], [-4.0, -1.5, 12.0]])
    parents = np.array([-1, 0, 1, 2, 1])
    level = np.array([0, 0, 0, 0, 1])
    return rest, parents, level


def _path(parents, j):
    """Non-root nodes from ``j`` up to the root's child."""
    out = []
    while parents[j] >= 0:
        out.append(j)
        j = parents[j]
    return out


def _posterior(rest, parents, level, target, prm):
    """The probabilistic solver's negative log posterior of one frame, as a function of every
    non-root node's rotation ω (n, 3), written out node by node: turns composed root to leaf
    (each turns its subtree about its parent joint), track, depth steps, shape, prior, rest."""
    N = len(parents)
    nonroot = np.flatnonzero(parents >= 0)
    height = float(np.ptp(rest[:, 2]))
    s_track, s_depth = prm.sigma_track * height, prm.depth_sigma * height
    order = [int(k) for k in np.argsort([len(_path(parents, k)) for k in range(N)]) if parents[k] >= 0]

    def sub(i):
        return [j for j in range(N) if i in _path(parents, j)]

    def angle(X, k):
        u = X[k] - X[parents[k]]
        g = parents[parents[k]]
        w = np.array([0, 0, 1.0]) if g < 0 else X[parents[k]] - X[g]
        return np.arccos(np.clip(u @ w / np.linalg.norm(u) / np.linalg.norm(w), -1, 1))

    alpha1 = {k: angle(rest, k) for k in nonroot}

    def f(flat):
        om = dict(zip(nonroot, flat.reshape(-1, 3)))
        X = rest.copy()
        depth = 0.0
        for i in order:
            R = rotations.rodrigues(om[i][None])[0]
            members = sub(i)
            moved = X[parents[i]] + (X[members] - X[parents[i]]) @ R.T
            depth += np.sum((moved[:, 1] - X[members, 1]) ** 2) / (2 * s_depth ** 2)
            X[members] = moved
        track = np.sum((X[:, [0, 2]] - target) ** 2) / (2 * s_track ** 2)
        shape = sum((angle(X, k) - alpha1[k]) ** 2 / (2 * (prm.sigma_shape * (1 + prm.sigma_shape_growth * level[k])) ** 2)
                    for k in nonroot)
        prior = np.sum(flat ** 2) * (1 / prm.prior_sigma ** 2 + 1 / prm.rest_sigma ** 2) / 2
        return track + depth + shape + prior

    return f


def test_one_frame_reaches_the_posterior_mode():
    """A fork of five nodes, one frame whose targets move by up to 1.5 px: the rotations the
    Gauss–Newton solve settles on (4 steps) give a posterior within 1 % of the best a general
    optimizer (BFGS over all 12 unknowns, from zero and from the solver's answer) finds."""
    from scipy.optimize import minimize
    rest, parents, level = _fork()
    move = np.array([[0, 0], [0.2, 0], [0.9, -0.2], [1.5, -0.4], [-0.6, 0.3]])
    tg = np.stack([rest[:, [0, 2]], rest[:, [0, 2]] + move])
    prm = motion.MotionParams(iterations=4, step_tolerance=0.0)
    m = motion.solve_motion(rest, parents, level, tg, prm)
    f = _posterior(rest, parents, level, motion.smooth_chain_targets(tg, parents)[1], prm)
    solved = m.accumulated[1, parents >= 0].astype(np.float64).ravel()
    best = min(minimize(f, x0, method="BFGS").fun for x0 in (np.zeros_like(solved), solved))
    assert best < f(np.zeros_like(solved)) * 0.5              # the targets really pull
    assert f(solved) <= best * 1.01, (f(solved), best)


def test_one_step_solves_the_linearized_posterior():
    """The sparse system of :mod:`rotation_solve` (two unknowns per node that meet only their
    parent's) gives the same step as the textbook normal equations over every node's rotation,
    written out densely: δx_j = Σ_{i ∈ path(j)} ω_i × (x_j − x_p(i)); rows for the track (x, z),
    the depth step each ω_i gives each node of its subtree, the linearized shape angle, prior and
    rest pull."""
    rng = np.random.default_rng(3)
    rest, parents, level = _fork()
    N = len(parents)
    prm = motion.MotionParams()
    height = float(np.ptp(rest[:, 2]))
    sys_ = rotation_solve.TreeSystem.of(parents)
    nodes, par = sys_.nodes, sys_.par
    grand = parents[par]
    n = len(nodes)
    conf = rng.uniform(0.2, 1.0, N)
    target = rest[:, [0, 2]] + rng.normal(0, 0.5, (N, 2))
    wf = rng.normal(0, 0.01, (n, 3))                     # a step already taken this frame …
    A0 = rng.normal(0, 0.05, (n, 3))                     # … and earlier frames' rotations
    X = rest + rng.normal(0, 0.3, rest.shape)
    terms = rotation_solve.FrameTerms(
        track=conf[nodes] / (prm.sigma_track * height) ** 2, target=target[nodes],
        inv_depth=1 / (prm.depth_sigma * height) ** 2, sigma_shape=prm.sigma_shape * (1 + prm.sigma_shape_growth * level[nodes]),
        alpha1=rotation_solve.branch_angles(rest, sys_, grand)[2], prior=1 / prm.prior_sigma ** 2,
        rest=1 / prm.rest_sigma ** 2, penalty=rotation_solve.PENALTY / (prm.sigma_track * height) ** 2)
    step, predicted = rotation_solve.gauss_newton_step(X, wf, A0, sys_, grand, terms)

    col = {int(k): 3 * c for c, k in enumerate(nodes)}
    rows, rhs = [], []

    def row(coeffs, value):                              # one residual: Σ coeffs · ω + value
        r = np.zeros(3 * n)
        for k, c in coeffs:
            r[col[k]:col[k] + 3] += c
        rows.append(r)
        rhs.append(value)

    cross = rotation_solve.cross_matrix
    for c, j in enumerate(nodes):
        sw = np.sqrt(terms.track[c])
        for axis in (0, 2):                              # K (ω_i × v) = −K [v]× ω
            coeffs = [(i, -sw * cross(X[j] - X[parents[i]])[axis]) for i in _path(parents, j)]
            row(coeffs, sw * (X[j, axis] - target[j, axis // 2]))
    for c, i in enumerate(nodes):
        for j in range(N):
            if i in _path(parents, j):                   # depth step of j from ω_i (wf_i + step)
                jy = -cross(X[j] - X[parents[i]])[1] / (prm.depth_sigma * height)
                row([(i, jy)], jy @ wf[c])
        u, w, alpha = (a[c] for a in rotation_solve.branch_angles(X, sys_, grand))
        ga = -np.cross(u, w) / np.sin(alpha) / terms.sigma_shape[c]
        row([(i, ga)], (alpha - terms.alpha1[c]) / terms.sigma_shape[c])
        for k in range(3):
            e = np.eye(3)[k]
            row([(i, e / prm.prior_sigma)], wf[c, k] / prm.prior_sigma)
            row([(i, e / prm.rest_sigma)], (A0[c, k] + wf[c, k]) / prm.rest_sigma)
    J, r0 = np.array(rows), np.array(rhs)
    dense = np.linalg.lstsq(J, -r0, rcond=None)[0].reshape(n, 3)
    assert np.abs(step - dense).max() <= 1e-6 * np.abs(dense).max(), (step, dense)
    # the predicted move is the linearized δx of the same step
    moved = np.array([sum(np.cross(dense[nodes.tolist().index(i)], X[j] - X[parents[i]]) for i in _path(parents, j))
                      for j in nodes])[:, [0, 2]]
    assert predicted == pytest.approx(moved, abs=1e-6 * np.abs(moved).max())


def test_turn_keeps_branch_lengths_and_turns_subtrees_about_their_joint():
    rest, parents, level = _fork()
    sys_ = rotation_solve.TreeSystem.of(parents)
    dw = np.zeros((len(parents), 3))
    dw[4] = [0, 0, np.pi / 2]                            # the side branch turns 90° about z at node 1
    X = rotation_solve.turn(rest, dw, sys_)
    assert X[[0, 1, 2, 3]] == pytest.approx(rest[[0, 1, 2, 3]])
    assert X[4] == pytest.approx(rest[1] + [1.5, -4.5, 4.0])
    dw[:] = 0
    dw[2] = [0.02, -0.03, 0.01]
    dw[1] = [0.01, 0.0, -0.02]
    X = rotation_solve.turn(rest, dw, sys_)
    e = np.flatnonzero(parents >= 0)
    assert np.linalg.norm(X[e] - X[parents[e]], axis=1) == pytest.approx(np.linalg.norm(rest[e] - rest[parents[e]], axis=1))
