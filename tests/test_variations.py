"""Tree variations from RGBA exemplars (issue 36 part 2, seed 000): mean value coordinates on hand
cases, the pinned contours, variations against their exemplars (weights (1, 0) give exemplar A
back; three variations of two differ in width over height and stay within the exemplars'; the
trunk's pixels land on the new trunk), and the batch run (files, record, one-line errors).
Exemplar seeds 200+ were never tuned on (tests/exemplar_trees.py)."""
import json
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from tree_from_video.core.generate.exemplars import CROWN_POINTS, N_POINTS, TRUNK_POINTS, crown_baseline, exemplar_from_rgba
from tree_from_video.core.generate.mvc import mvc_weights, warp_map
from tree_from_video.core.generate.variations import (
    VariationParams,
    box_aspect,
    make_variation,
    make_variations,
    trunk_polygon_mask,
)

from exemplar_trees import exemplar_tree
from samples import ROOT

BATCH = os.path.join(ROOT, "batch.py")


def test_mvc_hand_cases():
    # the unit square's centre: a quarter each (HF06 eq. 6 by symmetry)
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    assert np.allclose(mvc_weights(np.array([[0.5, 0.5]]), sq), 0.25)
    # on the square at (0.25, 0.5): tan(α/2) by hand. Vertices seen at angles; α_0 (v0→v1) etc.
    p = np.array([0.25, 0.5])
    s = sq - p
    ang = np.arctan2(s[:, 1], s[:, 0])
    alpha = (np.roll(ang, -1) - ang + np.pi) % (2 * np.pi) - np.pi
    r = np.linalg.norm(s, axis=1)
    w = (np.tan(np.roll(alpha, 1) / 2) + np.tan(alpha / 2)) / r
    assert np.allclose(mvc_weights(p[None], sq)[0], w / w.sum(), atol=1e-12)
    # linear precision on a non-convex polygon (an L), inside and outside: Σ λ_i v_i = p
    ell = np.array([[0, 0], [3, 0], [3, 1], [1, 1], [1, 3], [0, 3]], float)
    pts = np.random.default_rng(5).uniform(-1, 4, (200, 2))
    lam = mvc_weights(pts, ell)
    assert np.allclose(lam.sum(1), 1.0)
    assert np.abs(lam @ ell - pts).max() < 1e-8
    # a polygon mapped onto itself: the warp is the identity (within the grid's interpolation)
    m = warp_map(ell * 30 + 10, ell * 30 + 10, (120, 120))
    yy, xx = np.mgrid[0:120, 0:120]
    assert np.abs(m[..., 0] - xx).max() < 1e-3 and np.abs(m[..., 1] - yy).max() < 1e-3


@pytest.mark.parametrize("seed,shape", [(201, "round"), (202, "cone"), (203, "umbrella")])
def test_pins_and_resampling(seed, shape):
    rgba, truth = exemplar_tree(seed, shape)
    e = exemplar_from_rgba(rgba, "x")
    c = e.contour
    assert c.shape == (N_POINTS, 2)
    # B the lowest point; R and L where the contour meets the crown's baseline, R right of L
    assert c[0, 1] >= c[:, 1].max() - 1.0
    r, l_ = c[TRUNK_POINTS], c[TRUNK_POINTS + CROWN_POINTS]
    assert abs(r[1] - e.baseline) <= 1.5 and abs(l_[1] - e.baseline) <= 1.5 and r[0] > l_[0]
    assert (c[TRUNK_POINTS:TRUNK_POINTS + CROWN_POINTS, 1] <= e.baseline + 1.5).all()     # the crown above it
    # uniform chord length within each segment (its last step to the next pin aside)
    for a, b in ((0, TRUNK_POINTS), (TRUNK_POINTS, TRUNK_POINTS + CROWN_POINTS)):
        step = np.linalg.norm(np.diff(c[a:b], axis=0), axis=1)
        assert step.std() / step.mean() < 0.35
    # the baseline found against the drawn one (normalized: the picture's rows map linearly)
    ys, xs = np.nonzero(rgba[..., 3] >= 128)
    side = max(ys.ptp() + 1, xs.ptp() + 1) / (1 - 2 * 0.04)
    top = (side - (ys.ptp() + 1)) / 2
    want = (truth["baseline"] - ys.min() + top) * e.size / side
    base_px, trunk = crown_baseline(e.rgba[..., 3] >= 128)
    height = (ys.ptp() + 1) * e.size / side
    print(f"{shape}: baseline {base_px} vs drawn {want:.0f} ({abs(base_px - want) / height:.1%} of the height)")
    assert abs(base_px - want) <= 0.1 * height and trunk.any()


def _exemplars(seed, shapes=("round", "cone")):
    a, _ = exemplar_tree(seed, shapes[0])
    b, _ = exemplar_tree(seed + 1, shapes[1])
    return exemplar_from_rgba(a, "A"), exemplar_from_rgba(b, "B")


@pytest.mark.parametrize("seed", [210, 220])
def test_weights_one_zero_give_exemplar_a(seed):
    ea, eb = _exemplars(seed)
    v = make_variation([ea, eb], np.array([1.0, 0.0]), np.array([1.0, 0.0]))
    # contour: the variation's silhouette against A's, chamfer as a share of the height
    def outline(mask):
        cs, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        return max(cs, key=len)[:, 0].astype(float)
    pa, pv = outline(ea.rgba[..., 3] >= 128), outline(v.rgba[..., 3] >= 128)
    d = np.linalg.norm(pa[:, None] - pv[None], axis=2)
    chamfer = 0.5 * (d.min(1).mean() + d.min(0).mean())
    h = float(np.ptp(pa[:, 1]))
    op = ea.rgba[..., 3] >= 128
    colour = np.abs(v.rgba[..., :3].astype(int) - ea.rgba[..., :3].astype(int))[op].mean()
    print(f"seed {seed}: chamfer {chamfer / h:.3%} of the height, colour difference {colour:.2f}/255")
    assert chamfer <= 0.01 * h and colour <= 2.0


@pytest.mark.parametrize("seed", [230, 240, 250])
def test_three_variations_differ_within_the_exemplars(seed):
    ea, eb = _exemplars(seed, ("cone", "umbrella"))
    lo, hi = sorted(box_aspect(e.rgba[..., 3] >= 128) for e in (ea, eb))
    assert hi - lo >= 0.2, "the exemplars should differ in shape for this test"
    vs = make_variations([ea, eb], VariationParams(count=3, seed=seed))
    asp = sorted(v.aspect for v in vs)
    print(f"seed {seed}: exemplars {lo:.3f}..{hi:.3f}, variations {np.round(asp, 3)}")
    assert min(np.diff(asp)) >= 0.05
    assert lo - 0.02 <= asp[0] and asp[-1] <= hi + 0.02
    for v in vs:
        assert np.isclose(v.weights.sum(), 1.0) and (v.weights >= 0).all() and v.weights.max() <= 0.85 + 1e-9
        # the trunk carried by the warp lies on the trunk the new contour bounds
        tp = trunk_polygon_mask(v.contour, v.rgba.shape[0])
        iou = (tp & v.trunk).sum() / max((tp | v.trunk).sum(), 1)
        print(f"  weights {np.round(v.weights, 3)}: trunk IoU {iou:.3f}")
        assert iou >= 0.8
    # reproducible by seed
    again = make_variations([ea, eb], VariationParams(count=3, seed=seed))
    assert all(np.array_equal(a.rgba, b.rgba) for a, b in zip(vs, again))


def _png(path, rgba):
    assert cv2.imwrite(str(path), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))
    return str(path)


def run(*args):
    p = subprocess.run([sys.executable, BATCH, *map(str, args)], capture_output=True, text=True, timeout=300)
    return p.returncode, p.stdout, p.stderr


def test_batch_variations(tmp_path):
    a = _png(tmp_path / "a.png", exemplar_tree(260, "round")[0])
    b = _png(tmp_path / "b.png", exemplar_tree(261, "umbrella")[0])
    out = tmp_path / "out"
    code, _, err = run("--variations", 3, "--exemplars", a, b, "--out", out, "--seed", 4, "--quiet")
    assert code == 0, err
    doc = json.loads((out / "variations.json").read_text())
    assert doc["count"] == 3 and doc["seed"] == 4 and len(doc["variations"]) == 3
    for v in doc["variations"]:
        img = cv2.imread(str(out / v["file"]), cv2.IMREAD_UNCHANGED)
        assert img.shape == (512, 512, 4) and (img[..., 3] == 0).any() and (img[..., 3] == 255).any()
        assert abs(sum(v["weights"]) - 1) < 1e-5
        assert abs(box_aspect(img[..., 3] >= 128) - v["width_over_height"]) < 1e-3
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "ok" and len(report["input"]["exemplars"]) == 2
    # nothing overwritten without --force; the same job is skipped; a changed exemplar runs again
    code, _, err = run("--variations", 3, "--exemplars", a, b, "--out", out, "--seed", 4)
    assert code == 0 and "skipped" in err
    _png(tmp_path / "b.png", exemplar_tree(262, "cone")[0])
    code, _, err = run("--variations", 3, "--exemplars", a, b, "--out", out, "--seed", 4)
    assert code == 2 and "--force" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("case", ["no_alpha", "opaque", "empty", "missing", "no_exemplars", "with_video"])
def test_bad_exemplars_one_line_exit_2(tmp_path, case):
    rgba = exemplar_tree(270, "round")[0]
    args = ["--variations", 2, "--out", tmp_path / "out"]
    if case == "no_alpha":
        args += ["--exemplars", str(tmp_path / "x.png")]
        assert cv2.imwrite(str(tmp_path / "x.png"), rgba[..., :3])
    elif case == "opaque":
        full = rgba.copy()
        full[..., 3] = 255
        args += ["--exemplars", _png(tmp_path / "x.png", full)]
    elif case == "empty":
        args += ["--exemplars", _png(tmp_path / "x.png", np.zeros_like(rgba))]
    elif case == "missing":
        args += ["--exemplars", tmp_path / "nope.png"]
    elif case == "with_video":
        args = [tmp_path / "v.mp4"] + args + ["--exemplars", _png(tmp_path / "x.png", rgba)]
    code, out, err = run(*args)
    print(err)
    assert code == 2 and err.startswith("error: ") and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err


@pytest.mark.parametrize("seed", [280, 281])
def test_a_photo_with_its_outline_is_an_exemplar(tmp_path, seed):
    """A drawn tree laid on a sky and a lawn, as a photo with a polygon around it: the cut-out
    (the trace's tree-against-background test) gives the tree's own silhouette back."""
    rgba, _ = exemplar_tree(seed)
    h, w = rgba.shape[:2]
    rng = np.random.default_rng(seed)
    sky = np.linspace(0, 1, h)[:, None, None] * np.array([60, 40, 10]) + np.array([235, 190, 150])   # BGR
    photo = np.broadcast_to(sky, (h, w, 3)).copy() + rng.normal(0, 3, (h, w, 3))
    ys, xs = np.nonzero(rgba[..., 3] >= 128)
    ground = ys.max() - 5
    photo[ground:] = np.array([60, 120, 80]) + rng.normal(0, 6, (h - ground, w, 3))     # a lawn at the foot
    a = rgba[..., 3:] / 255.0
    photo = (photo * (1 - a) + rgba[..., 2::-1] * a).clip(0, 255).astype(np.uint8)
    path = str(tmp_path / "photo.jpg")
    cv2.imwrite(path, photo, [cv2.IMWRITE_JPEG_QUALITY, 92])
    hull = cv2.convexHull(np.stack([xs, ys], 1).astype(np.int32))[:, 0]
    centre = hull.mean(0)
    poly = (centre + (hull - centre) * 1.08).round().tolist()                  # a loose polygon around it
    (tmp_path / "outline.json").write_text(json.dumps(poly))
    from tree_from_video.core.generate.exemplars import read_exemplar
    cut = read_exemplar(path, outline=str(tmp_path / "outline.json"))
    true = exemplar_from_rgba(rgba, "truth")
    a1, a2 = cut.rgba[..., 3] >= 128, true.rgba[..., 3] >= 128
    iou = (a1 & a2).sum() / (a1 | a2).sum()
    print(f"seed {seed}: the photo's cut-out against the tree's own alpha IoU {iou:.3f}")
    assert iou >= 0.85 and cut.has_trunk
    code, _, err = run("--variations", 2, "--exemplars", path, _png(tmp_path / "b.png", exemplar_tree(seed + 10)[0]),
                       "--exemplar-outlines", tmp_path / "outline.json", "-", "--out", tmp_path / "out", "--quiet")
    assert code == 0, err
    code, _, err = run("--variations", 2, "--exemplars", path, "--exemplar-outlines", "a.json", "b.json",
                       "--out", tmp_path / "out2")
    assert code == 2 and "one per exemplar" in err
