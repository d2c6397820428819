"""The synthetic samples themselves: every wind variant has what it promises, measured from its truth and
its frames (leaf cards that turn, thin branches that swing, gusts that lean the crown, flicker and cloud
shadows, a foreground branch across the crown, a palm, the 30 s / 160x120 / 1080p H.264 / variable-frame-
rate clips), the seeds are documented, the flow reference agrees with the truth, and the first sample
set is unchanged (byte for byte)."""
import hashlib
import json
import os
import shutil
import subprocess

import cv2
import numpy as np
import pytest

from tree_from_video.sample_videos import synth_tree as st

from groundtruth import dominant_frequency
from motion_metrics import flow_reference_correlation
from samples import COMMITTED, generate, video_path

WIND = st.WIND_VARIANTS
ALL_SEEDS = {v: st.SEEDS[v]["dev"] + st.SEEDS[v]["held_out"] for v in st.VARIANTS}


def scene_and_truth(variant: str, seed: int, **kw):
    """Scene and truth arrays of a variant (no video, no visibility: fast)."""
    sc = st.build_scene(st.config_for(variant, seed=seed, **kw))
    return sc, st.truth_arrays(sc)


def psnr_blurred(a: np.ndarray, b: np.ndarray, sigma: float = 1.5) -> float:
    """PSNR (dB) after a Gaussian blur of both images (sensor noise and codec grain mostly removed)."""
    a = cv2.GaussianBlur(a.astype(np.float32), (0, 0), sigma)
    b = cv2.GaussianBlur(b.astype(np.float32), (0, 0), sigma)
    return float(10 * np.log10(255.0 ** 2 / max(np.mean((a - b) ** 2), 1e-12)))


# --- the first sample set is unchanged ---------------------------------------------------------

#: sha256 (first 16 hex) of each first-set variant at 48 frames, computed with synth_tree.py before the
#: wind options existed: (every truth array but ``visible_frac``, sorted by key; ``times`` is new) -- numpy
#: only, the same with numpy 1.26, 2.2 and 2.5 -- and per OpenCV build (``visible_frac`` and frames 0, 1 and
#: 47): its anti-aliased drawing differs by a level here and there between builds. Recorded on the venv
#: (OpenCV 4.11), real Blender 4.3 (4.10) and bpy 5.3 (5.0).
OLD_TRUTH = {"broad": "9714b5ece1d58138", "conifer": "512c762a04b26637", "sparse": "7ce8cdeed4e22814",
             "hard": "1c6250370496a6b6", "gentle": "e1e6229b645af981", "grey": "01f930b6cd957f9d",
             "dense": "3d003323a825bc1d"}
#: the same frames drawn on another CPU (AMD EPYC, no AVX-512: OpenCV's drawing takes other SIMD
#: paths there), recorded on it with the code before the wind options (b8eda87)
OLD_DRAWN_OTHER_CPU = {
    "4.11.0": {"broad": "1822b1ea8feeb22f", "conifer": "1ed25b8b8c3d0704", "sparse": "253e16c45d5f56ec",
               "hard": "d0146351391486ce", "gentle": "4c6fea4bf7ffc932", "grey": "8c2773455c748cf0",
               "dense": "c222091868999764"},
}
OLD_DRAWN = {
    "4.11.0": {"broad": "7068fd0839879cbe", "conifer": "93dbf0bbdfd399a5", "sparse": "253e16c45d5f56ec",
               "hard": "d0146351391486ce", "gentle": "09bae369c6393d70", "grey": "8c2773455c748cf0",
               "dense": "c222091868999764"},
    "4.10.0": {"broad": "77f83ab1b4690ea2", "conifer": "2146ab4f14531a4e", "sparse": "f8a10647a3df9aad",
               "hard": "a3a2518b5472fbda", "gentle": "c5b9698effab881d", "grey": "3f4730b625d48875",
               "dense": "791ce73d8a151a19"},
    "5.0.0": {"broad": "20281eda868a91ba", "conifer": "b396742821ff4f97", "sparse": "65d5a8b25428f86a",
              "hard": "ee0628b57efc2e51", "gentle": "4e8fc094f10e1edb", "grey": "f31d6b3421af70c0",
              "dense": "ffbed3b10a2d12a6"},
}


@pytest.mark.parametrize("variant", st.OLD_VARIANTS)
def test_first_sample_set_is_byte_identical(variant):
    sc = st.build_scene(st.config_for(variant, frames=48))
    ta = st.truth_arrays(sc, st._visibility(sc)[0])
    h, hd = hashlib.sha256(), hashlib.sha256()
    for k in sorted(ta):
        if k in ("times", "visible_frac"):
            continue
        h.update(k.encode())
        h.update(np.ascontiguousarray(ta[k]).tobytes())
    assert h.hexdigest()[:16] == OLD_TRUTH[variant]
    assert set(ta) - {"times"} == set(np.load(os.path.join(COMMITTED, "broad", "truth.npz")).files)
    assert np.array_equal(ta["times"], np.arange(48) / 24.0)
    hd.update(np.ascontiguousarray(ta["visible_frac"]).tobytes())
    for f in (0, 1, 47):
        hd.update(st.render_frame(sc, f).tobytes())
    assert cv2.__version__ in OLD_DRAWN, (f"no drawn reference for OpenCV {cv2.__version__}: record one by running "
                                          "this hash on the commit before the wind options (git log sample_videos)")
    assert hd.hexdigest()[:16] in (OLD_DRAWN[cv2.__version__][variant],
                                   OLD_DRAWN_OTHER_CPU.get(cv2.__version__, {}).get(variant))


@pytest.mark.parametrize("name", ["broad", "sparse"])
def test_committed_samples_regenerate(name):
    """The committed truth.npz is what the generator gives today, array for array (``visible_frac``, a share
    of ~48 sampled label images, exactly with the OpenCV it was made with and within a few samples elsewhere),
    and the committed video's first frames are today's frames (39.6-40.1 dB blurred PSNR measured, mp4v
    grain; frame 3 in place of frame 0: 31-36 dB, another seed: 16 dB)."""
    folder = os.path.join(COMMITTED, name)
    with np.load(os.path.join(folder, "truth.npz")) as z:
        committed = {k: z[k] for k in z.files}
    sc = st.build_scene(st.config_for(name, frames=len(committed["nodes2d"])))
    ta = st.truth_arrays(sc, st._visibility(sc)[0])
    for k, a in committed.items():
        assert a.dtype == ta[k].dtype, k
        if k == "visible_frac" and cv2.__version__ != "4.11.0":
            d = np.abs(a - ta[k])
            assert d.max() <= 0.1 and d.mean() <= 0.01, (k, d.max(), d.mean())     # measured 0.06 / 0.004
        else:
            assert np.array_equal(a, ta[k]), k
    cap = cv2.VideoCapture(os.path.join(folder, "video.mp4"))
    frames = [cap.read()[1] for _ in range(3)]
    cap.release()
    for f, img in enumerate(frames):
        assert psnr_blurred(img, st.render_frame(sc, f)) >= 38.0, f
    assert psnr_blurred(frames[0], st.render_frame(sc, 3)) < 37.0


# --- seeds --------------------------------------------------------------------------------------

def test_every_variant_has_dev_and_held_out_seeds_documented():
    readme = open(os.path.join(COMMITTED, "README.md"), encoding="utf-8").read()
    assert set(st.SEEDS) == set(st.VARIANTS)
    for v, s in st.SEEDS.items():
        assert s["dev"] and len(s["held_out"]) >= 2 and not set(s["dev"]) & set(s["held_out"]), v
        assert st.config_for(v).seed == s["dev"][0], v
        row = next((line for line in readme.splitlines() if line.startswith(f"| `{v}`")), None)
        assert row is not None, f"README has no row for {v}"
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[-2] == ", ".join(map(str, s["dev"])) and cells[-1] == ", ".join(map(str, s["held_out"])), row


@pytest.mark.parametrize("variant", WIND)
def test_wind_variants_stay_in_the_frame(variant):
    for seed in ALL_SEEDS[variant]:
        sc, ta = scene_and_truth(variant, seed)
        p = ta["nodes2d_image"]
        w, h = int(ta["width"]), int(ta["height"])
        assert (p[..., 0] >= 0).all() and (p[..., 0] <= w - 1).all(), (variant, seed)
        assert (p[..., 1] >= 0).all() and (p[..., 1] <= h - 1).all(), (variant, seed)
        leaves = st.leaf_polygons(sc, 0)
        inside = (leaves[..., 0] >= 0) & (leaves[..., 0] < w) & (leaves[..., 1] >= 0)
        assert inside.mean() >= 0.999, (variant, seed)
        assert 0.7 * 0.8 * h <= float(ta["height_px"]) <= 0.9 * h, (variant, seed)


# --- leaf cards turn ----------------------------------------------------------------------------

def _orientation(poly: np.ndarray) -> np.ndarray:
    d = poly[:, 0] - poly[:, 3]
    return np.arctan2(d[:, 1], d[:, 0])


@pytest.mark.parametrize("variant", [v for v in WIND if st.config_for(v).leaf_turn_deg[1] > 0])
def test_leaf_cards_turn_5_to_15_degrees_at_2_to_6_hz(variant):
    """Each leaf's turn, measured as the angle between its polygon's axis with and without turning (the
    same seed without ``leaf_turn_deg`` has the same leaves), has an amplitude of 5-15° and a dominant
    frequency of 2-6 Hz, each leaf its own phase; its width and brightness change as it turns."""
    cfg = st.config_for(variant)
    frames = min(cfg.frames, 96)
    seeds = ALL_SEEDS[variant][:2] if variant in ("long", "hd") else ALL_SEEDS[variant]
    for seed in seeds:
        sc = st.build_scene(st.config_for(variant, seed=seed, frames=frames))
        ref = st.build_scene(st.config_for(variant, seed=seed, frames=frames, leaf_turn_deg=(0.0, 0.0)))
        pick = np.random.default_rng(0).choice(len(sc.leaves.cluster), min(300, len(sc.leaves.cluster)), replace=False)
        polys = np.stack([st.leaf_polygons(sc, f)[pick] for f in range(frames)])
        refs = np.stack([st.leaf_polygons(ref, f)[pick] for f in range(frames)])
        ang = np.degrees(np.unwrap(np.stack([_orientation(p) - _orientation(r) for p, r in zip(polys, refs)]), axis=0))
        amp = 0.5 * (ang.max(0) - ang.min(0))
        assert np.percentile(amp, 2) >= 4.5 and amp.max() <= 15.0 + 1e-6, (variant, seed, np.percentile(amp, [0, 50, 100]))
        times = sc.times[:frames]
        freq = np.array([dominant_frequency(a, cfg.fps, times) for a in ang.T])
        assert ((freq >= 1.8) & (freq <= 6.2)).mean() >= 0.97, (variant, seed, np.percentile(freq, [0, 50, 100]))
        phase = sc.leaves.turn_phase[pick]
        assert np.std(np.cos(phase)) > 0.6 and np.std(np.sin(phase)) > 0.6          # phases spread
        width = np.linalg.norm(polys[:, :, 1] - polys[:, :, 5], axis=-1)
        assert np.median(width.max(0) / width.min(0) - 1.0) >= 0.03, variant          # the card foreshortens
        lum = np.stack([np.asarray(st.leaf_colors(sc, f))[pick] @ [0.114, 0.587, 0.299] for f in range(0, frames, 2)])
        assert np.median(lum.max(0) / np.maximum(lum.min(0), 1) - 1.0) >= 0.05, variant  # and its shading changes


# --- thin branches swing -----------------------------------------------------------------------

@pytest.mark.parametrize("variant", [v for v in WIND if st.config_for(v).thin_swing_deg[1] > 0])
def test_thin_branches_swing_5_to_15_degrees(variant):
    """The angle between a thinnest branch's chord and its parent's last segment, from the true nodes,
    swings by 5-15° (half its range) at the recorded frequency."""
    for seed in ALL_SEEDS[variant][:2]:
        _, ta = scene_and_truth(variant, seed, frames=min(st.config_for(variant).frames, 240))
        par, bid = ta["parents"], ta["branch_id"]
        n3 = ta["nodes3d"].astype(np.float64)
        thin = np.flatnonzero(ta["swing_deg"] > 0)
        assert len(thin) >= 10, (variant, seed)
        amp = []
        for b in thin:
            nodes = np.flatnonzero(bid == b)
            j = par[nodes[0]]
            c, p = n3[:, nodes[-1]] - n3[:, j], n3[:, j] - n3[:, par[j]]
            cos = (c * p).sum(-1) / np.linalg.norm(c, axis=-1) / np.linalg.norm(p, axis=-1)
            a = np.degrees(np.arccos(np.clip(cos, -1, 1)))
            amp.append(0.5 * np.ptp(a))
            f = dominant_frequency(a, float(ta["fps"]), ta["times"])
            assert 0.7 <= f <= 2.1, (variant, seed, b, f)
        ratio = np.array(amp) / ta["swing_deg"][thin]
        # sampled at fps, a swing's peak may fall between frames: >= cos(pi f / fps) of it (0.91 for tiny)
        assert 0.9 <= ratio.min() and ratio.max() <= 1.005 and np.median(ratio) >= 0.99, (variant, seed)
        assert min(amp) >= 4.5 and max(amp) <= 15.05, (variant, seed, min(amp), max(amp))


# --- strong gusts lean the crown ---------------------------------------------------------------

@pytest.mark.parametrize("variant", [v for v in WIND if st.config_for(v).gust_lean[1] > 0])
def test_gusts_lean_the_crown_by_5_to_10_percent_within_a_second(variant):
    """The crown top's x position with the gusts minus without them (the same seed, the gusts' own
    random stream), in share of the true height: every gust peaks at 5-10 % (long: 5-8 %), reaches 90 % of
    its peak within 1 s of its onset, and nothing leans before the first gust (frame 1 at rest)."""
    cfg = st.config_for(variant)
    lo, hi = cfg.gust_lean
    for seed in ALL_SEEDS[variant]:
        _, a = scene_and_truth(variant, seed)
        _, b = scene_and_truth(variant, seed, gust_lean=(0.0, 0.0))
        top = st.crown_top(a["nodes3d"][0].astype(np.float64))
        d = (a["nodes2d"][:, top, 0].mean(1) - b["nodes2d"][:, top, 0].mean(1)) / float(a["height_px"])
        t = a["times"]
        assert len(a["gust_onset"]) == cfg.gust_count >= 2
        assert np.abs(d[t < a["gust_onset"][0]]).max() < 1e-4
        for on, rise in zip(a["gust_onset"], a["gust_rise"]):
            i = np.flatnonzero((t >= on) & (t <= on + rise + 0.5))
            peak = np.abs(d[i]).max()
            t90 = t[i[np.argmax(np.abs(d[i]) >= 0.9 * peak)]] - on
            assert lo - 0.003 <= peak <= hi + 0.003, (variant, seed, on, peak)
            assert t90 <= 1.0, (variant, seed, on, t90)
        assert np.abs(d).max() * float(a["height_px"]) >= lo * float(a["height_px"]) - 1.0


# --- light: flicker and cloud shadows ----------------------------------------------------------

def test_flicker_gain_has_its_range_and_a_slow_and_a_fast_part():
    """Measured from rendered frames (cloud shadows off, noise on): the frame / clean-frame ratio is the
    recorded gain within 1 %; the gain spans 1 ± 0.15 (the issue asks 10-20 %), and both a slow part
    (< 0.5 Hz) and a fast one (> 2 Hz) carry at least 10 % of its variance."""
    for seed in ALL_SEEDS["flicker"]:
        sc, ta = scene_and_truth("flicker", seed, cloud_shadow=0.0)
        g = ta["light_gain"].astype(np.float64)
        assert 0.10 <= g.max() - 1.0 <= 0.20 and 0.10 <= 1.0 - g.min() <= 0.20, (seed, g.min(), g.max())
        for f in range(0, 240, 20):
            clean = st.render_clean(sc, f).astype(np.float64)
            ok = (clean > 40) & (clean < 200)
            ratio = np.median(st.render_frame(sc, f)[ok] / clean[ok])
            assert abs(ratio - g[f]) <= 0.01, (seed, f, ratio, g[f])
        spec = np.abs(np.fft.rfft(g - g.mean())) ** 2
        fr = np.fft.rfftfreq(len(g), 1.0 / float(ta["fps"]))
        assert spec[(fr > 0) & (fr < 0.5)].sum() >= 0.1 * spec.sum(), seed
        assert spec[fr > 2.0].sum() >= 0.1 * spec.sum(), seed


def test_cloud_shadows_darken_and_drift_across_the_frame():
    """Measured from rendered frames (flicker off): the frame / clean-frame ratio has shadows at least
    60 % as deep as recorded, and the shadow pattern moves by the recorded velocity (the best match of
    one ratio image in the other 1 s earlier, within 1.5 px)."""
    for seed in ALL_SEEDS["flicker"][:2]:
        sc, ta = scene_and_truth("flicker", seed, flicker=0.0)
        ratios = []
        for f in (0, 24):
            clean = np.maximum(st.render_clean(sc, f).astype(np.float32).mean(-1), 1.0)
            ratios.append(cv2.GaussianBlur(st.render_frame(sc, f).astype(np.float32).mean(-1) / clean, (0, 0), 3))
        depth = float(ta["shadow_depth"])
        assert ratios[0].min() <= 1.0 - 0.6 * depth and ratios[0].max() >= 0.97, (seed, ratios[0].min())
        m = 32                                          # frame 24's middle, found in frame 0's ratio
        score = cv2.matchTemplate(ratios[0], ratios[1][m:-m, m:-m], cv2.TM_CCOEFF_NORMED)
        _, best, _, (px, py) = cv2.minMaxLoc(score)
        dx, dy = m - px, m - py
        v = ta["shadow_velocity"] * (ta["times"][24] - ta["times"][0])
        assert best >= 0.9, (seed, best)
        assert abs(dx - v[0]) <= 1.5 and abs(dy - v[1]) <= 1.5, (seed, dx, dy, v)
        assert 12.0 <= np.linalg.norm(ta["shadow_velocity"]) <= 26.0


# --- a blurred branch in front of the crown ----------------------------------------------------

def test_foreground_branch_crosses_the_crown_and_its_mask_covers_it():
    for seed in ALL_SEEDS["foreground"]:
        sc, ta = scene_and_truth("foreground", seed)
        mask = ta["foreground_mask"]
        assert mask.shape == (240, 360, 480) and mask.dtype == bool
        crown = ta["nodes2d"][0][ta["depth_level"] >= 1]
        cx, w = 0.5 * (crown[:, 0].min() + crown[:, 0].max()), np.ptp(crown[:, 0])
        band = slice(int(np.percentile(crown[:, 1], 35)), int(np.percentile(crown[:, 1], 65)))
        xs = []
        for f in range(0, 240, 4):
            cols = np.flatnonzero(mask[f, band].any(0))
            if len(cols):
                xs.append(cols.mean())
        assert min(xs) <= cx - 0.2 * w and max(xs) >= cx + 0.2 * w, (seed, cx, w, min(xs), max(xs))
        lab = st.render_labels(sc, 0, foreground=False)
        tree = (lab == st.LABEL_BRANCH) | (lab == st.LABEL_LEAF)
        assert _labels_mark_the_mask(sc, mask)
        cover = max((mask[f] & tree).sum() / tree.sum() for f in range(0, 240, 8))
        assert cover >= 0.08, (seed, cover)
        # the mask holds every pixel the branch changes: renders with and without it differ only inside
        plain = st.build_scene(st.config_for("foreground", seed=seed, foreground=False))
        for f in (0, 40, 120, 200):
            diff = np.abs(st.render_clean(sc, f).astype(int) - st.render_clean(plain, f).astype(int)).max(-1)
            assert (mask[f][diff > 12]).mean() >= 0.995, (seed, f)
            assert (diff[mask[f]] > 12).mean() >= 0.5, (seed, f)


def _labels_mark_the_mask(sc, mask) -> bool:
    """Frame 1's labels mark the foreground exactly where the truth's mask is."""
    lab = st.render_labels(sc, 0)
    return bool(np.array_equal(lab == st.LABEL_FOREGROUND, mask[0]))


# --- the palm ----------------------------------------------------------------------------------

def test_palm_has_one_trunk_and_8_to_14_drooping_fronds_of_leaflets():
    bent = 0
    for seed in ALL_SEEDS["palm"]:
        sc, ta = scene_and_truth("palm", seed)
        par, part, frond = ta["parents"], ta["node_part"], ta["frond_id"]
        n0 = ta["nodes3d"][0].astype(np.float64)
        nf = int(ta["frond_count"])
        assert 8 <= nf <= 14 and set(np.unique(frond[frond >= 0])) == set(range(nf)), seed
        assert part[0] == 0 and ((part == 0) == (frond < 0)).all()
        trunk = np.flatnonzero(part == 0)
        kids = np.bincount(par[trunk[1:]], minlength=len(par))
        assert (kids[trunk] <= 1).all() and (part[par[trunk[1:]]] == 0).all(), seed   # one chain from the root
        top = trunk[kids[trunk] == 0]
        assert len(top) == 1, seed
        seg = np.diff(n0[trunk], axis=0)
        cosang = seg[0] @ seg[-1] / np.linalg.norm(seg[0]) / np.linalg.norm(seg[-1])
        bent += np.degrees(np.arccos(np.clip(cosang, -1, 1))) >= 5.0
        length = np.linalg.norm(seg, axis=1).sum()
        droop, leaflets = 0, np.bincount(frond[sc.leaves.node], minlength=nf)
        for j in range(nf):
            nodes = np.flatnonzero(frond == j)
            assert par[nodes[0]] == top[0] and (par[nodes[1:]] == nodes[:-1]).all(), (seed, j)
            assert len(nodes) >= 6
            arc = np.linalg.norm(np.diff(n0[np.r_[top[0], nodes]], axis=0), axis=1).sum()
            assert arc >= 0.3 * length, (seed, j, arc, length)
            droop += n0[nodes[-1], 2] < n0[nodes, 2].max() - 0.1 * arc
            assert leaflets[j] >= 40, (seed, j)
            # a bending chain: the angle between its first and last segment changes over the clip
            p = ta["nodes3d"][:, np.r_[top[0], nodes]].astype(np.float64)
            a, b = p[:, 1] - p[:, 0], p[:, -1] - p[:, -2]
            ang = np.degrees(np.arccos(np.clip((a * b).sum(-1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1),
                                               -1, 1)))
            assert np.ptp(ang) >= 3.0, (seed, j, np.ptp(ang))
        assert droop >= 0.6 * nf, (seed, droop, nf)
    assert bent >= len(ALL_SEEDS["palm"]) // 2, bent


# --- the 30 s, the 160x120, the 1080p H.264 and the variable-frame-rate clips ----------------

def test_long_clip_lasts_30_seconds_and_tiny_is_160x120_and_sways_pixels():
    """long: 720 frames over 30 s. tiny: 160x120 frames of a ~94 px conifer whose median node moves
    4+ px from its frame-1 place and by ~1 px a frame at its fastest (measured 0.85-1.36 px)."""
    _, ta = scene_and_truth("long", 0)
    assert ta["nodes2d"].shape[0] == 720 and ta["times"][-1] >= 29.9 and float(ta["fps"]) == 24.0
    for seed in ALL_SEEDS["tiny"]:
        sc, ta = scene_and_truth("tiny", seed)
        assert st.render_frame(sc, 0).shape == (120, 160, 3)
        d = np.linalg.norm(ta["nodes2d"] - ta["nodes2d"][:1], axis=-1)
        assert np.median(d.max(0)) >= 4.0, (seed, np.median(d.max(0)))        # several px in a ~94 px tree
        step = np.linalg.norm(np.diff(ta["nodes2d"], axis=0), axis=-1)
        assert np.median(step.max(0)) >= 0.8, seed                             # ~1 px per frame at 15 fps


def _ffprobe(path: str, entries: str) -> dict:
    out = subprocess.run(["ffprobe", "-v", "error", "-select_streams", "v:0", "-show_entries", entries, "-of", "json",
                          path], capture_output=True, check=True, text=True).stdout
    return json.loads(out)


@pytest.mark.slow
def test_hd_clip_is_h264_1920x1080(tmp_path):
    assert shutil.which("ffmpeg") and shutil.which("ffprobe"), "install ffmpeg (Debian: apt-get install -y ffmpeg)"
    folder = generate("hd", str(tmp_path / "hd"))
    path = video_path(folder)
    info = _ffprobe(path, "stream=codec_name,width,height,pix_fmt")["streams"][0]
    assert info == {"codec_name": "h264", "width": 1920, "height": 1080, "pix_fmt": "yuv420p"}
    assert os.path.getsize(path) < 8e6
    sc = st.build_scene(st.config_for("hd"))
    cap = cv2.VideoCapture(path)
    n = 0
    while True:
        ok, img = cap.read()
        if not ok:
            break
        assert img.shape == (1080, 1920, 3)
        if n in (0, 30):
            assert psnr_blurred(img, st.render_frame(sc, n)) >= 38.0, n    # the frames, in BGR order
        n += 1
    assert n == 48


@pytest.mark.slow
def test_vfr_clip_has_irregular_timestamps_and_a_header_fps_that_lies(tmp_path):
    assert shutil.which("ffmpeg") and shutil.which("ffprobe"), "install ffmpeg (Debian: apt-get install -y ffmpeg)"
    folder = generate("vfr", str(tmp_path / "vfr"))
    path = video_path(folder)
    assert path.endswith(".mkv")
    with np.load(os.path.join(folder, "truth.npz")) as z:
        times, fps, header = z["times"], float(z["fps"]), float(z["header_fps"])
    dt = np.diff(times)
    assert dt.min() > 0 and dt.std() / dt.mean() >= 0.3 and dt.max() >= 3 * np.median(dt)     # irregular, with gaps
    assert fps == pytest.approx((len(times) - 1) / times[-1])
    cap = cv2.VideoCapture(path)
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(header) and abs(header - fps) >= 10
    declared = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    sc = st.build_scene(st.config_for("vfr"))
    got = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        got.append(cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0)
        if len(got) in (1, 50):
            assert psnr_blurred(img, st.render_frame(sc, len(got) - 1)) >= 38.0
    assert len(got) == len(times) == 96 and declared != 96
    assert np.abs(np.array(got) - times).max() <= 0.0015
    pts = [float(fr["pts_time"]) for fr in _ffprobe(path, "frame=pts_time")["frames"]]
    assert np.abs(np.array(pts) - times).max() <= 0.0015
    assert _ffprobe(path, "stream=r_frame_rate")["streams"][0]["r_frame_rate"] == f"{int(header)}/1"


# --- the metrics -------------------------------------------------------------------------------

def test_dominant_frequency_uses_irregular_frame_times():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.lognormal(0, 0.5, 200)) / 12.0
    x = np.sin(2 * np.pi * 1.3 * t)
    assert dominant_frequency(x, 12.0, t) == pytest.approx(1.3, abs=0.02)
    regular = np.arange(200) / 12.0
    y = np.sin(2 * np.pi * 1.3 * regular)
    assert dominant_frequency(y, 12.0, regular) == dominant_frequency(y, 12.0)


@pytest.mark.slow
def test_flow_reference_agrees_with_the_truth(tmp_path):
    """The real-footage reference scored on the true nodes of a gust clip: ≥ 0.9 (measured 0.94 on 72
    frames); the same nodes reversed in time or shuffled score < 0.3; on the foreground clip the branch in
    front misleads the reference (measured 0.50) unless its mask excludes the nodes it covers (0.96 over
    the 14 that move enough)."""
    folder = generate("gusts", str(tmp_path / "gusts"), frames=72)
    mask = cv2.imread(os.path.join(folder, "mask.png"), cv2.IMREAD_GRAYSCALE)
    with np.load(os.path.join(folder, "truth.npz")) as z:
        n2 = z["nodes2d"].astype(np.float64)
    r = flow_reference_correlation(video_path(folder), mask, n2)
    assert r["n"] == 30 and r["corr"] >= 0.9 and 0.8 <= r["amp"] <= 1.25, r
    rev = flow_reference_correlation(None, mask, n2[::-1].copy(), reference=r["ref"])
    shuffled = n2.copy()
    shuffled[1:] = n2[1:][np.random.default_rng(0).permutation(len(n2) - 1)]
    shuf = flow_reference_correlation(None, mask, shuffled, reference=r["ref"])
    assert rev["corr"] < 0.3 and shuf["corr"] < 0.3, (rev["corr"], shuf["corr"])
    folder = generate("foreground", str(tmp_path / "fg"), frames=72)
    mask = cv2.imread(os.path.join(folder, "mask.png"), cv2.IMREAD_GRAYSCALE)
    with np.load(os.path.join(folder, "truth.npz")) as z:
        n2, fg = z["nodes2d"].astype(np.float64), z["foreground_mask"]
    plain = flow_reference_correlation(video_path(folder), mask, n2)
    clean = flow_reference_correlation(None, mask, n2, reference=plain["ref"], exclude=fg)
    assert clean["n"] >= 10 and clean["corr"] >= plain["corr"] + 0.1, (plain["corr"], clean["corr"], clean["n"])
