"""A tree from one photo on real photos (issue 35): the photos in ``real_photos/photos.json``
(Wikimedia Commons files another public repository keeps, each with its licence and credit; fetched,
never committed) run through ``batch.py PHOTO --outline ... --preview``, with the outline drawn round
each (where the file has one) and with ``--outline auto``; prints what each run measured (the found
outline's IoU with the drawn one) and writes ``docs/real_photos.jpg`` (each photo the file allows
beside its preview render, with its credit; the found outline drawn in red on the photo).

    # fetch the repository first (the tool library's fetch), then:
    .venv/bin/python benchmarks/real_photos.py --git /work/.mirror/kenakofer+anki-tree-identification/repo [--work DIR]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import cv2
import numpy as np

from _package import ROOT, load_package

HERE = os.path.join(ROOT, "benchmarks", "real_photos")


def fetch_file(git: str, commit: str, path: str, dest: str) -> None:
    """Write ``path`` as the repository at ``git`` (a git directory) holds it at ``commit`` to ``dest``."""
    blob = subprocess.run(["git", "--git-dir", git, "show", f"{commit}:{path}"], capture_output=True, check=True).stdout
    with open(dest, "wb") as fh:
        fh.write(blob)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--git", required=True, help="git directory of the fetched repository")
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "tfv_real_photos"))
    ap.add_argument("--picture", default=os.path.join(ROOT, "docs", "real_photos.jpg"))
    args = ap.parse_args()
    load_package()
    from tree_from_video.core.outline import polygon_to_mask
    from tree_from_video.core.reconstruct.photo_outline import photo_outline
    from tree_from_video.core.tree3d import load_tree
    with open(os.path.join(HERE, "photos.json"), encoding="utf-8") as fh:
        doc = json.load(fh)
    os.makedirs(args.work, exist_ok=True)
    rows, tiles = [], []
    for name, p in doc["photos"].items():
        photo = os.path.join(args.work, name + os.path.splitext(p["path"])[1].lower())
        fetch_file(args.git, doc["commit"], p["path"], photo)
        img = cv2.imread(photo)
        drawn = None
        outlines = ["auto"]
        if "outline" in p:
            outline = os.path.join(args.work, name + ".json")
            with open(outline, "w", encoding="utf-8") as fh:
                json.dump(p["outline"], fh)
            drawn = polygon_to_mask(np.asarray(p["outline"], float), img.shape[1], img.shape[0])
            outlines.insert(0, outline)
        for outline in outlines:
            auto = outline == "auto"
            out = os.path.join(args.work, "out_" + name + ("_auto" if auto else ""))
            run = subprocess.run([sys.executable, os.path.join(ROOT, "batch.py"), photo, "--outline", outline,
                                  "--out", out, "--preview", "--no-video", "--seconds", "2", "--force", "--quiet"],
                                 capture_output=True, text=True)
            how = "found" if auto else "drawn"
            if run.returncode:
                rows.append((name, how, "-", f"exit {run.returncode}: {run.stderr.strip().splitlines()[-1]}",
                             "", "", "", ""))
                continue
            tree = load_tree(os.path.join(out, "tree3d.npz"))
            warn = [ln for ln in run.stderr.splitlines() if ln.startswith("warning:")]
            leaf = tree.meta["leaf_colour"]["colour"]
            hue = cv2.cvtColor(np.uint8([[np.round(np.asarray(leaf)[::-1] * 255)]]), cv2.COLOR_BGR2HSV)[0, 0, 0] * 2
            tm = tree.meta.get("tree_map", {})
            iou = "-"
            mine = None
            if auto:
                mine = photo_outline(img).mask       # what the run found (the same cut, seeded)
                if drawn is not None:
                    iou = f"{(mine & drawn).sum() / (mine | drawn).sum():.2f}"
            rows.append((name, how, iou, tree.meta["form"], tree.n_nodes,
                         f"{tm.get('share', float('nan')):.3f} ({'used' if tm.get('used') else 'not used'})",
                         f"{leaf[0]:.2f}, {leaf[1]:.2f}, {leaf[2]:.2f} (hue {hue}°)", len(warn)))
            if not p.get("picture") or (auto and drawn is not None):
                continue                              # the file's licence, or its drawn outline's row is shown
            shown = img.copy()
            if mine is not None:
                contours, _ = cv2.findContours(mine.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
                cv2.drawContours(shown, contours, -1, (0, 0, 255), 2)
            prev = cv2.imread(os.path.join(out, "preview.png"))
            h = 360
            row = np.hstack([cv2.resize(x, (int(x.shape[1] * h / x.shape[0]), h), interpolation=cv2.INTER_AREA)
                             for x in (shown, prev)])
            cv2.putText(row, p["credit"].split(", https")[0], (6, h - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                        (255, 255, 255), 1, cv2.LINE_AA)
            tiles.append(row)
    print("| photo | outline | IoU with the drawn | form traced | nodes | tree map: share told apart | leaf colour sRGB "
          "| warnings |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(str(x) for x in r) + " |")
    if tiles:
        w = max(t.shape[1] for t in tiles)
        pic = np.vstack([np.pad(t, ((0, 0), (0, w - t.shape[1]), (0, 0)), constant_values=255) for t in tiles])
        cv2.imwrite(args.picture, pic, [cv2.IMWRITE_JPEG_QUALITY, 82])
        print(f"-> {args.picture}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
