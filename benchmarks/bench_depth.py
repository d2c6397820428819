"""The lift with learned depth against the lift with the outline's envelope (issue 35), on the
samples (dev seeds) and on held-out seeds of every variant: the symmetric 3D chamfer of the
frame-1 skeleton against the true tree over the tree height (best of both depth signs), and over
a flat lift's (the true tree flattened to depth 0): below 1 beats flat. The traced skeleton laid
flat (depth 0) is printed beside it: its ratio is what the 2D trace alone costs, and a lift over it
("/ own flat") is what the lift's depth gains or loses on the same trace.

Each clip is generated with 24 frames (the lift reads frame 1 and the traced skeleton; the motion
is not part of it), traced once, then lifted both ways.

    .venv/bin/python benchmarks/bench_depth.py [--work DIR] [--variants broad,conifer,...] [--seeds dev,held_out]
    .venv/bin/python benchmarks/bench_depth.py --forms 3 --oracle     # + what signs and magnitudes cost
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from dataclasses import replace

import cv2
import numpy as np

from _package import ROOT, load_package

VARIANTS = ("broad", "conifer", "sparse", "hard", "grey", "gentle", "dense", "gusts", "tiny", "palm")


def _clips(args, generate, synth_tree):
    """(variant or form, seed set, seed, folder) of every clip asked for, generated once."""
    if args.forms:
        sys.path.insert(0, os.path.join(ROOT, "scripts"))
        import depth_data
        made: dict = {}
        k = 0
        while min([made.get(f, 0) for f in depth_data.FORMS]) < args.forms:
            seed = 960_000 + k
            k += 1
            cfg, form = depth_data.config(seed)
            if made.get(form, 0) >= args.forms:
                continue
            made[form] = made.get(form, 0) + 1
            folder = os.path.join(args.work, f"form_{seed}")
            if not os.path.exists(os.path.join(folder, "truth.npz")):
                synth_tree.generate(replace(cfg, frames=24, jpeg_quality=0), folder)
            yield form, "unseen", seed, folder
        return
    for v in args.variants.split(","):
        for kind in args.seeds.split(","):
            for seed in synth_tree.SEEDS[v][kind]:
                yield v, kind, seed, generate(v, os.path.join(args.work, f"{v}_{seed}"), seed=seed, frames=24)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "tree_depth_bench"))
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--seeds", default="dev,held_out")
    ap.add_argument("--forms", type=int, default=0,
                    help="instead: this many trees of every form of the depth network's data generator "
                         "(scripts/depth_data.py), seeds it never trained on")
    ap.add_argument("--oracle", action="store_true",
                    help="also print what the learned lift loses to its depth signs and magnitudes "
                         "(tests/groundtruth.py depth_oracles)")
    args = ap.parse_args()
    load_package()
    sys.path.insert(0, os.path.join(ROOT, "tests"))
    from tree_from_video.core import pipeline
    from tree_from_video.core.reconstruct import learned_depth as ld
    from tree_from_video.core.reconstruct.lift import LiftParams, lift
    from tree_from_video.sample_videos import synth_tree

    from groundtruth import depth_oracles, lift_scores
    from samples import generate, load_truth, plain_settings

    net = ld.shared_net()
    fit = net.fit
    rows = []
    oracles: list[dict] = []
    for v, kind, seed, folder in _clips(args, generate, synth_tree):
        if True:
            if True:
                truth = load_truth(folder)
                s = plain_settings()
                res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
                sk = res.skeleton
                params = LiftParams(conifer=res.form == "conifer")
                frame = pipeline.first_frame(res)
                depth = net.predict(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), res.outline.mask,
                                    sk.nodes2d[0].astype(np.float64), sk.parents)
                out = {}
                for name, kw, pr in (("envelope", {}, params),
                                     ("learned", {"depth": depth, "fit": fit}, params),
                                     ("scaled", {"depth": depth, "fit": fit}, replace(params, depth_prior=False)),
                                     ("prior", {"depth": depth, "fit": fit}, replace(params, depth_crown=False))):
                    L = lift(sk, res.outline, pr, **kw)
                    r = lift_scores(L.nodes, sk.parents, sk.nodes2d[0, 0], truth)
                    out[name] = r["chamfer"] / r["flat_truth"]
                    if name == "learned" and args.oracle:
                        oracles.append(depth_oracles(L.nodes, sk.parents, sk.nodes2d[0, 0], truth))
                        print("    " + "  ".join(f"{k} {x:.2f}" for k, x in oracles[-1].items()))
                flat = L.nodes.copy()
                flat[:, 1] = 0.0
                r = lift_scores(flat, sk.parents, sk.nodes2d[0, 0], truth)
                out["own flat"] = r["chamfer"] / r["flat_truth"]
                rows.append((v, kind, seed, out["envelope"], out["learned"], out["own flat"]))
                print(f"{v:<10}{kind:<9}{seed:>4}  " + "  ".join(f"{k} {x:.2f}" for k, x in out.items()), flush=True)
    print("\n| variant | seeds | 3D chamfer / flat truth's: envelope | learned | own trace flat "
          "| learned / own flat (worst) |")
    print("|---|---|---|---|---|---|")
    for kind in dict.fromkeys(r[1] for r in rows):
        sel = [r for r in rows if r[1] == kind]
        for v in dict.fromkeys(r[0] for r in sel):
            e = [r[3] for r in sel if r[0] == v]
            ln = [r[4] for r in sel if r[0] == v]
            fl = [r[5] for r in sel if r[0] == v]
            own = np.array(ln) / np.array(fl)
            print(f"| {v} | {kind} | {np.mean(e):.2f} | {np.mean(ln):.2f} | {np.mean(fl):.2f} "
                  f"| {np.mean(own):.2f} ({own.max():.2f}) |")
        own = np.array([r[4] / r[5] for r in sel])
        print(f"| **mean** | {kind} | **{np.mean([r[3] for r in sel]):.2f}** | **{np.mean([r[4] for r in sel]):.2f}** "
              f"| {np.mean([r[5] for r in sel]):.2f} | {own.mean():.2f} ({own.max():.2f}) |")
    if oracles:
        print("\nthe learned lift against its oracles (mean over the trees; chamfer / flat truth's): "
              + ", ".join(f"{k} {np.mean([o[k] for o in oracles]):.2f}" for k in oracles[0]))


if __name__ == "__main__":
    main()
