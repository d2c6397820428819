"""The reconstruction on every sample variant x seed against its ground truth: the measurement
harness of issue 18 (motion that holds in real wind). One table per variant, a row per seed:

- ``ch1/H`` frame-1 chamfer / height and ``cover`` (tests/groundtruth.py ``score``);
- ``2D`` and ``3D`` tip motion: median Pearson correlation of the x displacement of matched tips,
  std ratio ours / true (``amp``), dominant-frequency error (``df`` Hz, from the clip's frame times);
  2D = the moving 2D skeleton, 3D = the solved 3D motion (``build_3d``) in the truth's frame;
- ``dα95°``: the 95th percentile of the change of branch angles of the built 3D tree (degrees),
  ``truth`` the truth's and ``rigid`` the truth's without the joints of its thinnest, swinging
  twigs (tests/motion_metrics.py ``true_bending``);
- ``fit max``, ``over``, ``unmeas``: how the 3D motion keeps to the measured 2D motion
  (``meta["motion_fit"]``): the largest reprojection at a measured node-frame (% of the height), the
  measured node-frames past the 3 % bound, the unmeasured share;
- ``tracks@10/30/60/last``: live tracks at that frame / live tracks at frame 1 (``result.tracks.valid``);
- ``cam px``: the largest error of the estimated camera motion at the frame centre, i.e. on a tripod
  clip the largest translation the tracker invented;
- ``barely``: whether the "the tree barely moves" warning fired;
- ``conf``: the worst frame's share of nodes whose motion confidence is at least node_motion's
  ``LOW_CONFIDENCE``; ``>=90%``: the share of frames where at least 90 % of the nodes are;
- the real-footage reference (tests/motion_metrics.py ``flow_reference_correlation``): ``ref`` the
  median correlation node vs dense-flow reference over the 30 nodes whose reference moves most
  (``ref amp`` their std ratio), ``same`` the truth correlation of those same 30 nodes (each matched
  to the nearest true node in frame 1), ``ref@true`` the reference scored on the true nodes (how far
  the reference itself can be trusted on that clip).

    .venv/bin/python benchmarks/motion_truth.py                       # dev seeds of every variant
    .venv/bin/python benchmarks/motion_truth.py --variants gusts,palm --seeds held_out --frames 120
    .venv/bin/python benchmarks/motion_truth.py --seeds 0,7 --json out.json

Samples are generated once into ``--out`` (default: a folder in the temp dir) and reused. Plain
settings (tests/samples.py ``plain_settings``): no twigs, straight round tubes; the leaves are placed.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
import traceback

import numpy as np
from scipy.spatial import cKDTree

from _package import ROOT, load_package

load_package()
sys.path.insert(0, os.path.join(ROOT, "tests"))

from tree_from_video.core import pipeline  # noqa: E402
from tree_from_video.core.reconstruct.node_motion import LOW_CONFIDENCE  # noqa: E402
from tree_from_video.sample_videos import synth_tree as st  # noqa: E402

from groundtruth import score  # noqa: E402
from motion_metrics import angle_changes, flow_reference, flow_reference_correlation, tip_motion, tip_motion_3d, true_bending  # noqa: E402
from samples import load_truth, plain_settings, video_path  # noqa: E402

SURVIVAL_FRAMES = (10, 30, 60)


def seeds_of(variant: str, which: str) -> list[tuple[int, str]]:
    """(seed, "dev" | "held") pairs of ``variant`` for ``which`` = dev | held_out | all | 'a,b,...'."""
    dev, held = st.SEEDS[variant]["dev"], st.SEEDS[variant]["held_out"]
    if which == "dev":
        return [(s, "dev") for s in dev]
    if which == "held_out":
        return [(s, "held") for s in held]
    if which == "all":
        return [(s, "dev") for s in dev] + [(s, "held") for s in held]
    wanted = [int(x) for x in which.split(",") if x.strip()]
    return [(s, "dev" if s in dev else "held" if s in held else "other") for s in wanted]


def sample(variant: str, seed: int, root: str, regenerate: bool = False) -> str:
    """Folder of the generated sample (generated once)."""
    folder = os.path.join(root, f"{variant}_{seed}")
    if regenerate or not os.path.exists(os.path.join(folder, "truth.npz")):
        st.generate(st.config_for(variant, seed=seed), folder)
    return folder


def camera_error(camera: np.ndarray, offset: np.ndarray, size: tuple[int, int]) -> float:
    """Largest |estimated - true| displacement (px) of the frame centre by the image -> frame-1 maps
    ``camera (F, 2, 3)``; the true map is the translation by ``-offset (F, 2)``."""
    c = np.array([size[0] / 2.0, size[1] / 2.0])
    est = np.einsum("fij,j->fi", camera[:, :, :2].astype(np.float64), c) + camera[:, :, 2] - c
    F = min(len(est), len(offset))
    return float(np.linalg.norm(est[:F] + offset[:F], axis=1).max())


def survival(valid: np.ndarray) -> list[float]:
    """Live tracks at frames 10, 30, 60 and the last, over live tracks at frame 1 (NaN past the clip)."""
    alive0 = max(int(valid[0].sum()), 1)
    out = [float(valid[f].sum()) / alive0 if f < len(valid) else float("nan") for f in SURVIVAL_FRAMES]
    return out + [float(valid[-1].sum()) / alive0]


def confidence_calibration(nodes2d: np.ndarray, confidence: np.ndarray, truth: dict) -> dict:
    """Whether the motion confidence means something: the median error of the node displacement
    (each node against the true node nearest it in frame 1, % of the height) over node-frames with
    confidence below ``LOW_CONFIDENCE`` (``low``) and at least 0.9 (``high``), and the share of
    node-frames that are low."""
    tn = truth["nodes2d"].astype(np.float64)
    F = min(len(tn), len(nodes2d))
    _, m = cKDTree(tn[0]).query(nodes2d[0])
    err = np.linalg.norm((nodes2d[1:F] - nodes2d[:1]) - (tn[1:F, m] - tn[:1, m]), axis=2)
    err = 100.0 * err / max(float(np.ptp(tn[0][:, 1])), 1e-9)
    c = np.asarray(confidence)[1:F]
    low, high = c < LOW_CONFIDENCE, c >= 0.9
    return {"low": float(np.median(err[low])) if low.any() else float("nan"),
            "high": float(np.median(err[high])) if high.any() else float("nan"), "low_share": float(low.mean())}


def same_node_truth_corr(nodes2d: np.ndarray, sel: np.ndarray, truth: dict) -> float:
    """Median x-displacement correlation of skeleton nodes ``sel`` with their nearest true node (frame 1)."""
    if len(sel) == 0:
        return float("nan")
    tn = truth["nodes2d"]
    F = min(len(tn), len(nodes2d))
    _, m = cKDTree(tn[0]).query(nodes2d[0, sel])
    out = []
    for i, j in zip(sel, m):
        a = nodes2d[:F, i, 0] - nodes2d[0, i, 0]
        b = tn[:F, j, 0] - tn[0, j, 0]
        out.append(float(np.corrcoef(a, b)[0, 1]) if a.std() > 1e-9 and b.std() > 1e-9 else 0.0)
    return float(np.median(out))


def measure(variant: str, seed: int, folder: str, frames: int | None = None, track: dict | None = None) -> dict:
    """Run the pipeline on one sample and score it (see the module docstring); ``track`` overrides
    fields of the tracking settings (``TrackParams``)."""
    truth = load_truth(folder)
    video = video_path(folder)
    n_truth = len(truth["nodes2d"])
    n = min(frames, n_truth) if frames else n_truth
    s = plain_settings(frames=f"0:{n}") if frames else plain_settings()
    for k, v in (track or {}).items():
        setattr(s.track, k, type(getattr(s.track, k))(v))
    t0 = time.perf_counter()
    res = pipeline.run(video, os.path.join(folder, "outline.json"), s)
    t_2d = time.perf_counter() - t0
    tree = pipeline.build_3d(res, s)
    t_3d = time.perf_counter() - t0 - t_2d
    sk = res.skeleton
    out: dict = {"variant": variant, "seed": seed, "frames": int(sk.nodes2d.shape[0]), "truth_frames": n,
                 "seconds_2d": t_2d, "seconds_3d": t_3d, "nodes": int(sk.n_nodes)}
    sc = score(sk.parents, sk.nodes2d, truth)
    out.update(chamfer1=sc.chamfer1, coverage=sc.coverage)
    out["tip2d"] = tip_motion(sk.parents, sk.nodes2d, truth)
    scale = float(tree.meta["metres_per_px"])
    out["tip3d"] = tip_motion_3d(tree.nodes3d.astype(np.float64) / scale, tree.parents,
                                 np.asarray(tree.meta["base_px"], float), truth)
    ours_da = np.degrees(angle_changes(tree.nodes3d.astype(np.float64), tree.parents))
    out["bend"] = {"ours": float(np.percentile(ours_da, 95)), **true_bending(truth, int(tree.nodes3d.shape[0]))}
    out["fit"] = tree.meta.get("motion_fit")
    out["survival"] = survival(res.tracks.valid)
    size = (int(res.outline.mask.shape[1]), int(res.outline.mask.shape[0]))
    out["tripod"] = bool(np.abs(truth["camera_offset"]).max() == 0)
    out["camera_px"] = camera_error(res.tracks.camera, truth["camera_offset"].astype(np.float64), size)
    out["barely_moves"] = any("barely moves" in w for w in res.warnings)
    conf = sk.confidence[1:] if sk.confidence is not None and len(sk.confidence) > 1 else np.ones((1, 1))
    share = (conf >= LOW_CONFIDENCE).mean(axis=1)           # per frame: share of confident nodes
    out["confident"] = {"worst_frame": float(share.min()), "median_frame": float(np.median(share)),
                        "frames_ge_90": float((share >= 0.9).mean())}
    if sk.confidence is not None:
        out["calibration"] = confidence_calibration(sk.nodes2d.astype(np.float64), sk.confidence, truth)
    out["warnings"] = res.warnings
    # the real-footage reference: one flow pass, sampled at our nodes and at the true ones
    rows = min(n, sk.nodes2d.shape[0])
    tn = truth["nodes2d"][:rows].astype(np.float64)
    pts = np.concatenate([sk.nodes2d[0], tn[0]])
    idx, disp = flow_reference(video, res.outline.mask, pts, rows)
    ours = flow_reference_correlation(video, res.outline.mask, sk.nodes2d[:rows], reference=(idx, disp[:, :sk.n_nodes]))
    true = flow_reference_correlation(video, res.outline.mask, tn, reference=(idx, disp[:, sk.n_nodes:]))
    out["ref"] = {"corr": ours["corr"], "amp": ours["amp"], "n": ours["n"],
                  "same_nodes_truth_corr": same_node_truth_corr(sk.nodes2d[:rows].astype(np.float64), ours["nodes"], truth),
                  "truth_corr": true["corr"], "truth_amp": true["amp"]}
    return out


HEADER = (f"{'seed':>9} {'ch1/H':>6} {'cover':>5} | {'2D corr':>7} {'amp':>5} {'df Hz':>5} | {'3D corr':>7} {'amp':>5} "
          f"{'df Hz':>5} | {'dα95°':>5} {'truth':>5} {'rigid':>5} | {'fit max':>7} {'over':>4} {'unmeas':>6} | "
          f"{'tracks@10':>9} {'@30':>4} {'@60':>4} {'@last':>5} | {'cam px':>6} {'barely':>6} | "
          f"{'ref':>5} {'refamp':>6} {'same':>5} {'ref@true':>8} | {'conf':>4} {'>=90%':>5} | {'s':>5}")


def _f(x: float, fmt: str) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)


def row(r: dict) -> str:
    if "error" in r:
        return f"{r['seed']:>4} {r['split']:<4} ERROR {r['error']}"
    sv = [_f(100 * v, ".0f") + "%" if not math.isnan(v) else "-" for v in r["survival"]]
    cam = _f(r["camera_px"], ".2f") + ("" if r["tripod"] else "*")
    return (f"{r['seed']:>4} {r['split']:<4} {_f(100 * r['chamfer1'], '5.2f')}% {_f(r['coverage'], '5.2f')} | "
            f"{_f(r['tip2d']['corr'], '7.2f')} {_f(r['tip2d']['amp'], '5.2f')} {_f(r['tip2d']['freq_err'], '5.2f')} | "
            f"{_f(r['tip3d']['corr'], '7.2f')} {_f(r['tip3d']['amp'], '5.2f')} {_f(r['tip3d']['freq_err'], '5.2f')} | "
            f"{_f(r['bend']['ours'], '5.1f')} {_f(r['bend']['all'], '5.1f')} {_f(r['bend']['rigid'], '5.1f')} | "
            f"{_f(100 * r['fit']['max'], '6.2f')}% {r['fit']['over']:>4} {_f(100 * r['fit']['unmeasured'], '5.1f')}% | "
            f"{sv[0]:>9} {sv[1]:>4} {sv[2]:>4} {sv[3]:>5} | {cam:>6} {'yes' if r['barely_moves'] else 'no':>6} | "
            f"{_f(r['ref']['corr'], '5.2f')} {_f(r['ref']['amp'], '6.2f')} {_f(r['ref']['same_nodes_truth_corr'], '5.2f')} "
            f"{_f(r['ref']['truth_corr'], '8.2f')} | {_f(r['confident']['worst_frame'], '4.2f')} "
            f"{_f(100 * r['confident']['frames_ge_90'], '4.0f')}% | {r['seconds_2d'] + r['seconds_3d']:5.1f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", default=",".join(st.VARIANTS), help="comma-separated (default: all)")
    ap.add_argument("--seeds", default="dev", help="dev | held_out | all | comma-separated seeds (default dev)")
    ap.add_argument("--frames", type=int, help="use only the first N frames of each clip")
    ap.add_argument("--out", default=os.path.join(tempfile.gettempdir(), "tree_motion_truth"),
                    help="folder of the generated samples (reused)")
    ap.add_argument("--track", action="append", default=[], metavar="FIELD=VALUE",
                    help="override a tracking setting (TrackParams), e.g. --track redetect_every=0")
    ap.add_argument("--regenerate", action="store_true", help="generate the samples again")
    ap.add_argument("--json", help="also write every measurement to this JSON file")
    a = ap.parse_args(argv)
    track = dict(kv.split("=", 1) for kv in a.track)
    variants = [v.strip() for v in a.variants.split(",") if v.strip()]
    bad = [v for v in variants if v not in st.VARIANTS]
    if bad:
        ap.error(f"unknown variants {bad}; choose from {', '.join(st.VARIANTS)}")
    print(f"motion against the truth: seeds {a.seeds}, frames {a.frames or 'all'}; samples in {a.out}")
    print("cam px: on a tripod clip the invented camera translation (* = clip with camera motion: the error)")
    results = []
    t_all = time.perf_counter()
    for v in variants:
        print(f"\n{v}  ({st.config_for(v).width}x{st.config_for(v).height}, {st.config_for(v).frames} frames)")
        print(HEADER)
        for seed, split in seeds_of(v, a.seeds):
            try:
                folder = sample(v, seed, a.out, a.regenerate)
                r = measure(v, seed, folder, a.frames, track)
            except Exception as e:                    # one failing clip must not end the table
                r = {"variant": v, "seed": seed, "error": f"{type(e).__name__}: {e}".splitlines()[0][:200],
                     "trace": traceback.format_exc()}
            r["split"] = split
            results.append(r)
            print(row(r), flush=True)
            for w in r.get("warnings", []):
                print(f"{'':>10}warning: {w[:150]}")
    print(f"\ntotal {time.perf_counter() - t_all:.0f} s")
    if a.json:
        with open(a.json, "w", encoding="utf-8") as fh:
            json.dump(results, fh, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
