"""Fit the species library shipped in species/*.json from the sample videos.

    .venv/bin/python scripts/make_species.py [--out species] [--work DIR] [--contours-only]

broad and sparse are the committed samples (sample_videos/); conifer and palm are generated with
tests/samples.py (variants "conifer" and "palm") into DIR, the conifer traced and lifted as one
(leader kept) and the palm as a palm (a trunk with a crown of fronds).
Each is reconstructed with the default settings (pipeline.run + build_3d, 10 m tall), then
species.fit_species writes <name>.json. With --contours-only the files' other numbers stay as they
are and only what was added since they were fitted is written into them: the source's crown contour
(``crown_contours``, for --envelope-variation) and its leaves' colour range (``leaves.colour_range``).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from package_loader import load_package  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "species"))
    ap.add_argument("--work", default=None, help="folder for the generated conifer sample")
    ap.add_argument("--contours-only", action="store_true",
                    help="keep each file's fitted numbers; add its source's crown contour and leaf colour range")
    args = ap.parse_args(argv)
    load_package()
    from tree_from_video.core.generate import species
    sys.path.insert(0, os.path.join(ROOT, "tests"))
    from tree_from_video.core import pipeline

    from samples import committed, generate, plain_settings
    work = args.work or tempfile.mkdtemp(prefix="species-")
    os.makedirs(args.out, exist_ok=True)
    for name in ("broad", "sparse", "conifer", "palm"):
        t0 = time.time()
        s = plain_settings()
        if name in ("conifer", "palm"):
            folder = generate(name, os.path.join(work, name))
            s.form = name
        else:
            folder = committed(name)
        res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
        tree = pipeline.build_3d(res, s, name=name)
        model = species.fit_species(tree, name)
        path = os.path.join(args.out, f"{name}.json")
        if args.contours_only:
            old = species.load_species(path)
            old.contours = model.contours
            if old.leaves is not None and model.leaves is not None:
                old.leaves["colour_range"] = model.leaves.get("colour_range")
            model = old
        species.save_species(path, model)
        print(f"{name}: {tree.n_nodes} nodes, {tree.n_frames} frames -> {path} "
              f"({time.time() - t0:.1f} s) {species.model_summary(model)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
