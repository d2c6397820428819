"""A tree from one photo (core/generate/photo.py, issue 35): frame 1 of samples saved as a JPEG through
batch.py — the skeleton traced on it against the sample's truth (chamfer ≤ 2.5 % of the height,
coverage ≥ 0.75), lifted with the learned depth, and swaying as its species (the tips' sway spectrum
over three sway seeds against the species' energy spectrum, and each seed's joints peaking within
one FFT bin of the species' dominant frequency); bad photos: one line, exit 2."""
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from tree_from_video.core.generate.batch import load_species_spec
from tree_from_video.core.reconstruct.lift import leader_nodes
from tree_from_video.core.tree3d import image_to_plane, load_tree

from groundtruth import chamfer_coverage
from motion_metrics import joints, tips
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


def tip_spectrum(x: np.ndarray) -> np.ndarray:
    """The power spectrum of ``x (F, T)`` summed over its columns (each mean removed), the zero bin
    dropped, normalized to sum 1: ``(F // 2 + 1,)``."""
    power = (np.abs(np.fft.rfft(x - x.mean(0), axis=0)) ** 2).sum(1)
    power[0] = 0.0
    return power / max(power.sum(), 1e-30)


def joint_peak_hz(nodes: np.ndarray, parents: np.ndarray, fps: float) -> float:
    """The peak (Hz) of the joints' mean power spectrum: at each joint the bone's unit direction
    minus its parent bone's over ``nodes (F, N, 3)`` (signed, so a straight joint swinging both
    ways keeps its frequency, where its angle would fold it to twice), mean removed, its power
    summed over x, y, z and normalized to sum 1, averaged over the joints. The species draws its
    energy ratios per node, so their mean over a tree's hundreds of joints peaks where the
    species' mean energy does; a tip's position sums a few large bones' rotations and its peak
    wanders with the draw."""
    c = joints(parents)
    a = nodes[:, c] - nodes[:, parents[c]]
    b = nodes[:, parents[c]] - nodes[:, parents[parents[c]]]
    v = a / np.linalg.norm(a, axis=-1, keepdims=True) - b / np.linalg.norm(b, axis=-1, keepdims=True)
    power = (np.abs(np.fft.rfft(v - v.mean(0), axis=0)) ** 2).sum(-1)
    power[0] = 0.0
    mean = (power / np.maximum(power.sum(0, keepdims=True), 1e-30)).mean(1)
    return float(np.fft.rfftfreq(len(nodes), 1.0 / fps)[int(np.argmax(mean))])


def species_spectrum(name: str, freqs: np.ndarray) -> np.ndarray:
    """A library species' mean energy ratios over its three axes, interpolated onto ``freqs (B,)``
    Hz (0 outside its kept bins and at 0 Hz), normalized to sum 1."""
    motion = load_species_spec(name)[0].motion
    energy = np.mean([m.energy / m.energy.sum() for m in motion], 0)
    out = np.interp(freqs, motion[0].freqs_hz, energy, left=0.0, right=0.0)
    out[freqs <= 0] = 0.0
    return out / out.sum()


def test_tip_spectrum_by_hand():
    """Two tips, 10 s at 10 fps (bins of 0.1 Hz): one at 0.5 Hz with amplitude 2, one at 1.5 Hz with
    amplitude 1 → powers 4 : 1 at those bins; a library species' spectrum sums to 1, none at 0 Hz."""
    t = np.arange(100) / 10.0
    x = np.stack([2 * np.sin(2 * np.pi * 0.5 * t) + 3.0, np.sin(2 * np.pi * 1.5 * t)], 1)
    spec = tip_spectrum(x)
    assert spec[5] == pytest.approx(0.8) and spec[15] == pytest.approx(0.2) and spec.sum() == pytest.approx(1.0)
    s = species_spectrum("broad", np.fft.rfftfreq(100, 0.1))
    assert s.sum() == pytest.approx(1.0) and s[0] == 0.0
    # a straight chain 0 → 1 → 2 → 3 whose joints at 1 and 2 swing both ways, 0.1 rad at 0.3 Hz and
    # 0.05 rad at 2 Hz: both joints peak at 0.3 Hz (their angle, folded at 0, would at 0.6 Hz)
    ang = 0.1 * np.sin(2 * np.pi * 0.3 * t) + 0.05 * np.sin(2 * np.pi * 2.0 * t)
    nodes = np.zeros((100, 4, 3))
    nodes[:, 1, 2] = 1.0
    nodes[:, 2] = nodes[:, 1] + np.stack([np.sin(ang), 0 * t, np.cos(ang)], 1)
    nodes[:, 3] = nodes[:, 2] + np.stack([np.sin(2 * ang), 0 * t, np.cos(2 * ang)], 1)
    assert joint_peak_hz(nodes, np.array([-1, 0, 1, 2]), 10.0) == pytest.approx(0.3)


def test_the_wind_rises_from_the_photos_pose():
    """Frame 1 is the photo's pose exactly, the wind at half strength halfway up its rise (the
    smoothstep 3u² − 2u³), full after it; bone lengths kept throughout."""
    from tree_from_video.core.generate.photo import PhotoMotion, sway, wind_rise
    rise = wind_rise(26, 10.0, 1.0)
    assert rise[0] == 0.0 and rise[5] == pytest.approx(0.5) and rise[2] == pytest.approx(3 * 0.04 - 2 * 0.008)
    assert (rise[10:] == 1.0).all() and (np.diff(rise) >= 0).all()
    assert (wind_rise(5, 10.0, 0.0) == 1.0).all()
    parents = np.array([-1, 0, 1, 1])
    rest = np.array([[0.0, 0, 0], [0, 0, 2.0], [1.0, 0, 3.0], [-1.0, 0.5, 3.0]])
    nodes = sway(load_species_spec("broad")[0], parents, rest, PhotoMotion(seconds=4.0), 10.0)
    assert np.array_equal(nodes[0], rest)
    moved = np.abs(nodes - rest).max(axis=(1, 2))
    assert moved[1] < 0.1 * moved[15:].max()                        # barely stirred a tenth of a second in
    lengths = np.linalg.norm(nodes[:, 1:] - nodes[:, parents[1:]], axis=2)
    assert np.allclose(lengths, lengths[0], atol=1e-9)


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
    # a photo's central leader (at every split the child reaching highest in the photo) stays in the
    # trunk's plane (LiftParams.leader): its mean pose over the sway (which swings about the rest
    # pose) within 0.5 % of the height; the traced nodes come first in the tree, the grown crown after
    n = len(parents)
    assert np.array_equal(tree.parents[:n], parents)
    lead = leader_nodes(parents, image_to_plane(nodes2d[0].astype(np.float64), nodes2d[0, 0]))
    mean = tree.nodes3d[:, :n].astype(np.float64).mean(0)
    off = float(np.abs(mean[lead, 1] - mean[0, 1]).max()) / float(np.ptp(tree.nodes3d[0][:, 2]))
    print(f"{variant}: the leader's {lead.sum()} nodes lie within {off:.2%} of the height of the trunk's plane")
    assert lead.sum() >= 3 and off < 0.005
    # the tips sway like the species: the tips' power spectrum (their x motion, summed over tips and
    # averaged over three sway seeds) against the species' mean energy ratios (its axes' Dirichlet
    # means, on the same frequency bins): correlation ≥ 0.7, and nearer (L1) to its own species than
    # to the library's other one. Not "the peak within one FFT bin of the species' dominant": the
    # species' sway is broadband (broad: 35 % of its energy at 0.67–0.8 Hz, the rest spread over
    # 0.13–1.5 Hz), so one realization's peak wanders over 0.12–1.0 Hz (8 seeds of the broad photo:
    # the peak of the summed spectrum within a bin in 4, the median of each tip's peak in 6), and
    # even 4 seeds' mean spectrum peaks at 0.50 Hz for one draw. Measured on 8 seeds of the broad
    # photo: every one of the 56 three-seed means nearer to broad than to conifer, correlation ≥ 0.84
    # … and, as the issue asks, the dominant frequency within one FFT bin of one of the species'
    # axes' dominant ones, taken from the joints (:func:`joint_peak_hz`): 8 of 8 sway seeds of the
    # broad photo peak at 0.62–0.87 Hz for the species' 0.67 and 0.8 Hz
    model = load_species_spec(species)[0]
    want = [m.dominant_hz for m in model.motion]
    bin_hz = tree.fps / tree.n_frames
    trees = [tree]
    spectra = [tip_spectrum(tree.nodes3d[:, tips(p), 0])]
    for seed in (1, 2):
        code, _, err = run(photo, "--outline", os.path.join(folder, "outline.json"), "--out", tmp_path / f"out{seed}",
                           "--no-video", "--seconds", "8", "--seed", seed)
        assert code == 0, err
        other_tree = load_tree(str(tmp_path / f"out{seed}" / "tree3d.npz"))   # the seed grows the crown, too
        trees.append(other_tree)
        spectra.append(tip_spectrum(other_tree.nodes3d[:, tips(other_tree.parents), 0]))
    ours = np.mean(spectra, 0)
    freqs = np.fft.rfftfreq(tree.n_frames, 1.0 / tree.fps)
    other = "conifer" if species == "broad" else "broad"
    own_spec, other_spec = species_spectrum(species, freqs), species_spectrum(other, freqs)
    corr = float(np.corrcoef(ours, own_spec)[0, 1])
    d_own, d_other = np.abs(ours - own_spec).sum(), np.abs(ours - other_spec).sum()
    print(f"{variant}: the sway's spectrum against {species}'s: correlation {corr:.2f}, L1 {d_own:.2f} "
          f"(against {other}'s {d_other:.2f})")
    assert corr >= 0.7 and d_own < d_other
    peaks = [joint_peak_hz(t.nodes3d.astype(np.float64), t.parents, t.fps) for t in trees]
    print(f"{variant}: the joints peak at {np.round(peaks, 3)} Hz; the species' axes {np.round(want, 3)}; "
          f"a bin {bin_hz:.3f} Hz")
    assert all(min(abs(hz - w) for w in want) <= bin_hz + 1e-9 for hz in peaks)
    assert np.ptp(tree.nodes3d[:, tips(p), 0], axis=0).mean() > 0.002 * float(np.ptp(tree.nodes3d[0][:, 2]))


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
    h, w = cv2.imread(frame_one_jpeg(committed("broad"), tmp_path / "size.jpg")).shape[:2]
    sky = np.clip(np.full((h, w, 3), (220.0, 170.0, 110.0)) + rng.normal(0, 3, (h, w, 3)), 0, 255).astype(np.uint8)
    sky[int(0.8 * h):] = (60, 120, 70)
    sky = _write(tmp_path / "sky.jpg", sky)            # sky over grass where the outline is: no tree in it
    cases = [(small, "at least 128 px"), (grey, "one flat colour"), (broken, "cannot be read as an image"),
             (gif, "animated GIF"), (sky, "no tree inside the outline")]
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
