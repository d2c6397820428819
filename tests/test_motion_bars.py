"""Issue 18's bars, measured on a held-out seed of every wind variant (seed 2: never tuned on; seed
3 is kept unseen for the issue's final measurement) with benchmarks/motion_truth.py's harness:

- 2D tip motion (x displacement of tips against the true nodes): correlation >= 0.9, amplitude
  ratio 0.8..1.25, dominant frequency within 0.05 Hz;
- frame-1 chamfer <= 1.5 % of the height, coverage >= 0.9;
- at every frame >= 90 % of the nodes have a motion confidence >= node_motion.LOW_CONFIDENCE;
- camera translation <= 0.3 px on a tripod; no "barely moves" warning on a swaying tree;
- the confidence means something: where at least 1 % of node-frames are below LOW_CONFIDENCE,
  their median displacement error is at least 1.5x that of the node-frames at 0.9 or more.

Where a variant does not reach a bar yet, :data:`GAPS` holds what it measured when the gap was
recorded and a floor under it: the test then guards against getting worse, and fails once the bar
is reached clearly, by a quarter of the floor's distance beyond the recorded value (delete the
entry then). The table prints with ``-s``.
"""

import pytest

from samples import motion_truth_harness

mt = motion_truth_harness()

SEED = 2
LOW = mt.LOW_CONFIDENCE
VARIANTS = ("flutter", "gusts", "flicker", "foreground", "conifer_storm", "palm", "long", "tiny", "hd", "vfr")

#: (variant, measure) -> (measured when recorded, floor the test holds it to); see the docstring
GAPS = {
    # 0.89 on the machine that recorded it, 0.907 on another with the same code and pins (the
    # same commit measured on both): it sits at the bar, so the gap stays until it clears it
    ("flicker", "tip_corr"): (0.90, 0.84),
    ("vfr", "confident"): (0.88, 0.75),
    ("foreground", "tip_corr"): (0.54, 0.45),                  # the branch in front is followed
    ("foreground", "confident"): (0.75, 0.65),
    ("palm", "confident"): (0.61, 0.5),                        # fluttering leaflets: short tracks
    ("palm", "chamfer"): (0.0150, 0.0165),
    # 0.91 before the LK image's half-size blur; the fronds' trace sits at the bar and moves by
    # ±0.03 with any change to the tracks (dev seeds 0.93 / 0.92 either way)
    ("palm", "coverage"): (0.88, 0.85),
    ("tiny", "chamfer"): (0.0172, 0.02),
    ("tiny", "coverage"): (0.69, 0.6),
    ("tiny", "confident"): (0.85, 0.75),
}

#: measure -> (bar, True when higher is better); amp_out: how far the amplitude ratio is outside 0.8..1.25
BARS = {"tip_corr": (0.9, True), "amp_out": (0.0, False), "freq_err": (0.05, False), "confident": (0.9, True),
        "chamfer": (0.015, False), "coverage": (0.9, True)}




@pytest.fixture(scope="module")
def samples(tmp_path_factory):
    return str(tmp_path_factory.mktemp("wind_held_out"))


def _values(r: dict) -> dict:
    amp = r["tip2d"]["amp"]
    return {"tip_corr": r["tip2d"]["corr"], "amp_out": max(0.0, 0.8 - amp, amp - 1.25), "freq_err": r["tip2d"]["freq_err"],
            "confident": r["confident"]["worst_frame"], "chamfer": r["chamfer1"], "coverage": r["coverage"]}


def _meets(v: float, bar: float, higher: bool) -> bool:
    return v >= bar if higher else v <= bar


def test_seed_is_held_out():
    import tree_from_video.sample_videos.synth_tree as st
    assert all(SEED in st.SEEDS[v]["held_out"] for v in VARIANTS)


@pytest.mark.parametrize("variant", VARIANTS)
def test_motion_bars_on_a_held_out_seed(variant, samples, capsys):
    r = mt.measure(variant, SEED, mt.sample(variant, SEED, samples))
    r["split"] = "held"
    with capsys.disabled():
        print(f"\n{variant}\n{mt.HEADER}\n{mt.row(r)}")
    vals = _values(r)
    problems = []
    for name, v in vals.items():
        bar, higher = BARS[name]
        ok = _meets(v, bar, higher)
        gap = GAPS.get((variant, name))
        if gap is None and not ok:
            problems.append(f"{name} {v:.3f} misses the bar {bar}")
        elif gap is not None and ok and _meets(v, gap[0] + (gap[0] - gap[1]) / 4, higher):
            problems.append(f"{name} {v:.3f} now meets the bar: delete GAPS[{variant!r}, {name!r}]")
        elif gap is not None and not ok and not _meets(v, gap[1], higher):
            problems.append(f"{name} {v:.3f} fell below the recorded gap's floor {gap[1]} (was {gap[0]})")
    if r["tripod"] and r["camera_px"] > 0.3:
        problems.append(f"camera {r['camera_px']:.2f} px invented on a tripod")
    if r["barely_moves"]:
        problems.append("'barely moves' warned on a swaying tree")
    cal = r["calibration"]
    if cal["low_share"] >= 0.01 and not cal["low"] >= 1.5 * cal["high"]:
        problems.append(f"confidence uncalibrated: error {cal['low']:.2f} % of H below {LOW:.1f}, "
                        f"{cal['high']:.2f} % at 0.9 or more")
    with capsys.disabled():
        print(f"confidence: {cal['low_share']:.1%} of node-frames low, median error {cal['low']:.2f} % of H "
              f"there, {cal['high']:.2f} % where >= 0.9")
    assert not problems, f"{variant} seed {SEED}: " + "; ".join(problems)
