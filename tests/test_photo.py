"""A tree from one photo (core/generate/photo.py, issue 35): frame 1 of samples saved as a JPEG through
batch.py — the skeleton traced on it against the sample's truth (chamfer ≤ 2.5 % of the height,
coverage ≥ 0.75), lifted with the learned depth, and swaying as its species (the dominant frequency
of the tips' sway is one of the species' within one FFT bin); bad photos: one line, exit 2."""
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from tree_from_video.core.generate.batch import load_species_spec
from tree_from_video.core.tree3d import load_tree

from groundtruth import chamfer_coverage
from samples import ROOT, committed, generate, load_truth

BATCH = os.path.join(ROOT, "batch.py")


def run(*args):
    p = subprocess.run([sys.executable, BATCH, *map(str, args)], capture_output=True, text=True, timeout=600)
    return p.returncode, p.stdout, p.stderr


def sample(variant: str, seed: int, tmp_path) -> str:
    """The committed sample, or a held-out seed generated (two frames: only frame 1 is used)."""
    if seed < 0:
        return committed(variant)
    return generate(variant, str(tmp_path / f"{variant}_{seed}"), seed=seed, frames=2)


def frame_one_jpeg(folder: str, path) -> str:
    cap = cv2.VideoCapture(os.path.join(folder, "video.mp4"))
    ok, frame = cap.read()
    cap.release()
    assert ok
    cv2.imwrite(str(path), frame, [cv2.IMWRITE_JPEG_QUALITY, 90])
    return str(path)


def dominant_hz(x: np.ndarray, fps: float) -> float:
    """The strongest frequency of ``x (F,)`` (mean removed), Hz."""
    spec = np.abs(np.fft.rfft(x - x.mean()))
    spec[0] = 0.0
    return float(np.fft.rfftfreq(len(x), 1.0 / fps)[int(np.argmax(spec))])


@pytest.mark.slow
@pytest.mark.parametrize("variant,seed,species", [("broad", -1, "broad"), ("sparse", -1, "broad"),
                                                  ("conifer", 101, "conifer"), ("gusts", 2, "broad")])
def test_photo_of_a_sample_traces_lifts_and_sways(tmp_path, variant, seed, species):
    folder = sample(variant, seed, tmp_path)
    photo = frame_one_jpeg(folder, tmp_path / "tree.jpg")
    out = tmp_path / "out"
    code, _, err = run(photo, "--outline", os.path.join(folder, "outline.json"), "--out", out,
                       "--no-video", "--seconds", "8")
    assert code == 0, err
    truth = load_truth(folder)
    with np.load(out / "skeleton.npz") as z:
        nodes2d, parents = z["nodes2d"], z["parents"]
    assert nodes2d.shape[0] == 1                                   # one frame traced
    ch, cov = chamfer_coverage(nodes2d[0], parents, truth["nodes2d"][0], truth["parents"], float(truth["height_px"]))
    print(f"{variant}: chamfer {ch:.2%} of the height, coverage {cov:.2f}")
    assert ch <= 0.025 and cov >= 0.75
    tree = load_tree(str(out / "tree3d.npz"))
    assert tree.meta["photo"]["species"] == species and tree.meta["depth"]["source"] == "learned"
    assert tree.n_frames == int(round(8 * tree.fps)) + 1
    # bone lengths kept by the sway (forward kinematics)
    p = tree.parents
    lengths = np.linalg.norm(tree.nodes3d[:, p >= 0] - tree.nodes3d[:, p[p >= 0]], axis=2)
    assert np.abs(lengths - lengths[0]).max() < 1e-4 * float(np.ptp(tree.nodes3d[0][:, 2]))
    # the tips sway at the species' frequencies: the median tip's dominant frequency is one of the
    # species' axes' dominant frequencies, within one FFT bin
    model = load_species_spec(species)[0]
    tips = np.setdiff1d(np.arange(len(p)), p)
    hz = np.median([dominant_hz(tree.nodes3d[:, t, 0], tree.fps) for t in tips])
    bin_hz = tree.fps / tree.n_frames
    want = [m.dominant_hz for m in model.motion]
    print(f"{variant}: tips sway at {hz:.3f} Hz; the species' axes {np.round(want, 3)}; a bin {bin_hz:.3f} Hz")
    assert min(abs(hz - w) for w in want) <= bin_hz + 1e-9
    assert np.ptp(tree.nodes3d[:, tips, 0], axis=0).mean() > 0.002 * float(np.ptp(tree.nodes3d[0][:, 2]))


def _write(path, img):
    assert cv2.imwrite(str(path), img)
    return str(path)


def test_bad_photos_one_line_exit_2(tmp_path):
    outline = os.path.join(committed("broad"), "outline.json")
    rng = np.random.default_rng(0)
    small = _write(tmp_path / "small.png", rng.integers(0, 255, (90, 120, 3), dtype=np.uint8))
    grey = _write(tmp_path / "grey.png", np.full((300, 400, 3), 128, np.uint8))
    broken = tmp_path / "broken.jpg"
    broken.write_text("not a picture")
    gif = tmp_path / "anim.gif"
    frames = tmp_path / "f%d.png"
    for k in range(3):
        _write(tmp_path / f"f{k}.png", rng.integers(0, 255, (160, 200, 3), dtype=np.uint8))
    subprocess.run(["ffmpeg", "-v", "error", "-y", "-framerate", "5", "-i", str(frames), str(gif)], check=True)
    cases = [(small, "at least 128 px"), (grey, "one flat colour"), (broken, "cannot be read as an image"),
             (gif, "animated GIF")]
    for path, words in cases:
        out = tmp_path / ("out_" + os.path.basename(str(path)))
        code, _, err = run(path, "--outline", outline, "--out", out)
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert code == 2 and words in lines[-1] and lines[-1].startswith("error:"), err
        assert "Traceback" not in err
    # a sway of no length, or a wind past the range
    photo = frame_one_jpeg(committed("broad"), tmp_path / "ok.jpg")
    for opt, value, words in (("--seconds", "0", "--seconds 0.0 out of range"), ("--wind", "20", "--wind 20.0 out of range")):
        code, _, err = run(photo, "--outline", outline, "--out", tmp_path / f"out_{opt[2:]}", opt, value)
        assert code == 2 and words in err.strip().splitlines()[-1], err
        assert not (tmp_path / f"out_{opt[2:]}").exists()
    # a video is not a photo's sway: --seconds with a video is still an error
    code, _, err = run(os.path.join(committed("broad"), "video.mp4"), "--outline", outline, "--out",
                       tmp_path / "v", "--seconds", "4")
    assert code == 2 and "--seconds only applies" in err
