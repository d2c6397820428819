"""How often the form read from a photo's found outline is right, on real photos (issue 35): the
whole-tree photos of ``real_photos/forms.json`` (a tree-identification deck's Wikimedia Commons
files, labelled conifer or broadleaf by the species in their names; fetched, never committed), each
outlined as ``batch.py PHOTO --outline auto`` outlines it (:func:`..core.reconstruct.run.read_outlines`)
and its form read as ``--form auto`` reads it (:func:`..core.reconstruct.form.detect_form`). Prints
each photo's reading and the table the README shows; the counts are what
:data:`..core.reconstruct.form.FOUND_PHOTO_RIGHT` quotes in the run's warning.

    # fetch the repository first (the tool library's fetch), then:
    .venv/bin/python benchmarks/real_photo_forms.py --git /work/.mirror/kenakofer+anki-tree-identification/repo
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile

from real_photos import HERE, fetch_file

from _package import load_package


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--git", required=True, help="git directory of the fetched repository")
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "tfv_real_photo_forms"))
    args = ap.parse_args()
    load_package()
    from tree_from_video.core.errors import InputError
    from tree_from_video.core.reconstruct.form import FOUND_PHOTO_RIGHT, detect_form
    from tree_from_video.core.reconstruct.run import read_outlines
    from tree_from_video.core.reconstruct.video import open_video
    with open(os.path.join(HERE, "forms.json"), encoding="utf-8") as fh:
        doc = json.load(fh)
    os.makedirs(args.work, exist_ok=True)
    read: dict[str, dict[str, int]] = {}
    for truth in ("conifer", "broadleaf"):
        read[truth] = {"conifer": 0, "broadleaf": 0, "no outline": 0}
        for k, path in enumerate(doc[truth]):
            photo = os.path.join(args.work, f"{truth}_{k:02d}{os.path.splitext(path)[1].lower()}")
            fetch_file(args.git, doc["commit"], path, photo)
            try:
                info = open_video(photo, 1.0)
                outline = read_outlines(info, 0, "auto", 1.0)[0]
            except InputError:
                read[truth]["no outline"] += 1
                print(f"{truth:<10}{os.path.basename(path)[:60]:<62} no tree found", flush=True)
                continue
            form, why = detect_form(outline.mask)
            read[truth][form] += 1
            print(f"{truth:<10}{os.path.basename(path)[:60]:<62} {form:<10} {why}", flush=True)
    print("\n| the tree is | photos | found no outline | read as conifer | read as broadleaf |")
    print("|---|---|---|---|---|")
    for truth, n in read.items():
        print(f"| {truth} | {sum(n.values())} | {n['no outline']} | {n['conifer']} | {n['broadleaf']} |")
    for form in ("conifer", "broadleaf"):
        right, said = read[form][form], read["conifer"][form] + read["broadleaf"][form]
        print(f"read as {form}: right {right} of {said}" + ("" if FOUND_PHOTO_RIGHT[form] == (right, said) else
                                                            f" (FOUND_PHOTO_RIGHT says {FOUND_PHOTO_RIGHT[form]})"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
