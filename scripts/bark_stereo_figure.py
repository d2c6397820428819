"""The README's picture of the bark height from two photos (docs/bark_stereo.jpg): a synthetic pair
(tests/bark_photos.bark_pair, seed 31), then photo 1's height from its shading, from the parallax
against photo 2 (core/detail/bark_stereo.py), and the true relief, each high-passed alike.

    .venv/bin/python scripts/bark_stereo_figure.py [OUT.jpg]
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path[:0] = [ROOT, os.path.join(ROOT, "tests")]
from package_loader import load_package  # noqa: E402

load_package()
import cv2  # noqa: E402
import numpy as np  # noqa: E402
from bark_photos import bark_pair  # noqa: E402

from tree_from_video.core.detail import bark_photo as bp  # noqa: E402


def grey(h: np.ndarray) -> np.ndarray:
    lo, hi = np.percentile(h, [1, 99])
    return cv2.cvtColor(np.clip((h - lo) / max(hi - lo, 1e-9) * 255, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)


def main(out: str) -> None:
    a, b, ha, _ = bark_pair(31)
    sigma = 40.0
    heights, said = bp.photo_heights([a, b], sigma)
    shading = bp.shading_height(bp.even_light(a), sigma)
    truth = ha - cv2.GaussianBlur(ha.astype(np.float32), (0, 0), sigma)
    tiles = [a, b, grey(shading), grey(heights[0]), grey(truth)]
    labels = ["photo 1", "photo 2", "height from shading", "height from parallax", "true relief"]
    row = []
    for img, text in zip(tiles, labels):
        small = cv2.resize(img, (320, 240), interpolation=cv2.INTER_AREA)
        cv2.rectangle(small, (0, 0), (320, 26), (0, 0, 0), -1)
        cv2.putText(small, text, (8, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)
        row.append(small)
    cv2.imwrite(out, np.concatenate(row, axis=1), [cv2.IMWRITE_JPEG_QUALITY, 85])
    print(f"{out}: photo 1's height: {said[0]}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "bark_stereo.jpg"))
