"""No real clip ends in a traceback (issue 31, item 5): every real clip of ``--clips`` (see
``real_clips.py``), and each one cropped, scaled (¼, ½, 2×), trimmed to its first 2 frames and to
its last 3, and re-encoded at low quality, goes through the batch job with its outline moved to
match, and the original also with ``--outline auto``. A run passes when it finishes, or stops
with one clear ``error:`` line (exit 2); an ``internal error`` fails. Prints one row per run:
exit code, seconds, warnings, and the last line.

    .venv/bin/python benchmarks/real_robustness.py --clips DIR [--only trees,webcam] [--work DIR]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

import cv2
import numpy as np
from real_clips import RealClip, run_batch, select, write_outline

#: longest side of a 2x variant (beyond it the variant is skipped, said in its row)
MAX_SIDE = 2600
#: frames kept of the 2x variants and the low-quality one (the sweep checks shapes, not length)
SHORT = 40


def probe(path: str) -> tuple[int, int, int]:
    """``(width, height, frames)`` of a video as OpenCV reads it (frames counted by reading)."""
    cap = cv2.VideoCapture(path)
    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    n = 0
    while cap.grab():
        n += 1
    cap.release()
    return w, h, n


def ffmpeg(src: str, out: str, vf: str | None, extra: list[str]) -> None:
    """Re-encode ``src`` to ``out`` (H.264) through the filter ``vf``."""
    cmd = ["ffmpeg", "-v", "error", "-y", "-i", src, "-an"]
    if vf:
        cmd += ["-vf", vf]
    cmd += extra + ["-c:v", "libx264", "-pix_fmt", "yuv420p", out]
    subprocess.run(cmd, check=True)


def variants(clip: RealClip, work: str) -> list[tuple[str, str, str]]:
    """``(name, video, outline.json)`` for every variant of ``clip`` (made in ``work``)."""
    w, h, n = probe(clip.video)
    poly = clip.outline
    out = [("original", clip.video, write_outline(poly, os.path.join(work, "outline.json"))),
           ("auto outline", clip.video, "auto")]
    # crop: the outline's box and 10 % around it, then a tight one cutting the crown's sides
    lo, hi = poly.min(0), poly.max(0)
    for name, grow in (("crop box", 0.1), ("crop tight", -0.15)):
        pad = grow * (hi - lo)
        x0, y0 = np.maximum(np.floor(lo - pad), 0).astype(int)
        x1, y1 = np.minimum(np.ceil(hi + pad), [w, h]).astype(int)
        cw, ch = (x1 - x0) // 2 * 2, (y1 - y0) // 2 * 2
        v = os.path.join(work, name.replace(" ", "_") + ".mp4")
        ffmpeg(clip.video, v, f"crop={cw}:{ch}:{x0}:{y0}", ["-frames:v", str(SHORT)])
        p = np.clip(poly - [x0, y0], 0, [cw - 1, ch - 1])
        out.append((name, v, write_outline(p, v[:-4] + ".json")))
    for s in (0.25, 0.5, 2.0):
        sw, sh = int(round(w * s / 2)) * 2, int(round(h * s / 2)) * 2
        name = f"scale {s:g}x"
        if max(sw, sh) > MAX_SIDE:
            out.append((name, "", f"skipped: {sw}x{sh} is over {MAX_SIDE} px"))
            continue
        v = os.path.join(work, f"scale_{s:g}.mp4")
        ffmpeg(clip.video, v, f"scale={sw}:{sh}", ["-frames:v", str(SHORT)] if s > 1 else [])
        out.append((name, v, write_outline(poly * [sw / w, sh / h], v[:-4] + ".json")))
    first = os.path.join(work, "first2.mp4")
    ffmpeg(clip.video, first, None, ["-frames:v", "2"])
    out.append(("first 2 frames", first, out[0][2]))
    last = os.path.join(work, "last3.mp4")
    ffmpeg(clip.video, last, f"select=gte(n\\,{max(n - 3, 0)})", ["-vsync", "vfr"])
    out.append(("last 3 frames", last, out[0][2]))
    low = os.path.join(work, "lowq.mp4")
    ffmpeg(clip.video, low, None, ["-frames:v", str(SHORT), "-crf", "48"])
    out.append(("low quality", low, out[0][2]))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", required=True, help="folder of the real clips (see real_clips.py)")
    ap.add_argument("--only", default="", help="comma-separated clip keys")
    ap.add_argument("--work", default="", help="folder for the variants (default: a temporary one)")
    args = ap.parse_args()
    clips = select(args.clips, args.only)
    failed = 0
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or tmp
        print(f"{'clip':<12} {'variant':<16} {'exit':>4} {'s':>6} {'warn':>4}  last line")
        for clip in clips:
            folder = os.path.join(work, clip.key)
            os.makedirs(folder, exist_ok=True)
            for name, video, outline in variants(clip, folder):
                if not video:
                    print(f"{clip.key:<12} {name:<16} {'-':>4} {'-':>6} {'-':>4}  {outline}", flush=True)
                    continue
                r = run_batch(video, outline, os.path.join(folder, "out"), clip.form if outline != "auto" else "auto")
                bad = "internal error" in r.last or r.code not in (0, 2)
                failed += bad
                print(f"{clip.key:<12} {name:<16} {r.code:>4} {r.seconds:>6.1f} {len(r.warnings):>4}  "
                      f"{'FAIL ' if bad else ''}{r.last[:110]}", flush=True)
    print(f"{failed} runs ended in an internal error")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
