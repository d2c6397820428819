"""Training pairs for the learned depth (issue 35): synthetic trees of every form
(``sample_videos/synth_tree.py``, which has the 3D truth), frame 1 rendered orthographically at a
random size, encoded as the product encodes a real frame (:mod:`core.reconstruct.learned_depth`),
and the depths the network learns, from the truth.

Per tree ``seed`` (reproducible: the form, the shape, the foliage and the frame size all come from
it): ``x (IN_CHANNELS, S, S)`` uint8 0/255-scaled input, ``y (OUT_CHANNELS, S, S)`` float32 unit
depths, ``w (OUT_CHANNELS, S, S)`` bool where each target is defined, and the form's name.

* the skeleton drawn is the true one as the trace would give it: nodes jittered by ~1 px, the
  thinnest branches dropped at random (a trace misses some), hidden branches kept;
* channel 0 of ``y``: the skeleton's depth (the front-most where branches cross) on its pixels;
* channels 1, 2: the crown's front depth and its interval to the back over the tree's pixels
  (leaves, their cards' corners and centres, and the branch segments).

Depths are ``(y_world − y_root) / H`` (``H`` the outline's height in px, as the product measures it),
+ away from the camera (synth_tree's painter draws high ``y`` first).

    .venv/bin/python scripts/depth_data.py --seeds 0:8 --out /tmp/depth8.npz   # a look at the data
"""
from __future__ import annotations

import argparse
import os
import sys

import cv2
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from package_loader import load_package  # noqa: E402

load_package()
from tree_from_video.core.reconstruct import learned_depth as ld  # noqa: E402
from tree_from_video.sample_videos import synth_tree as st  # noqa: E402

#: the forms drawn from, with their synth_tree presets and the overrides' ranges
FORMS = ("broad", "conifer", "sparse", "dense", "palm", "young", "bare")


def config(seed: int) -> tuple[st.SynthConfig, str]:
    """The synthetic tree of ``seed`` and its form: the form, shape, foliage and frame size all
    drawn from the seed."""
    rng = np.random.default_rng([35, seed])
    form = FORMS[int(rng.integers(len(FORMS)))]
    h = int(rng.choice([240, 360, 480, 720]))
    w = int(round(h * rng.uniform(1.0, 1.78)))
    common = dict(width=w, height=h, frames=1, seed=100_000 + seed, noise_sigma=float(rng.uniform(0.0, 5.0)),
                  height_frac=float(rng.uniform(0.6, 0.85)), bark=str(rng.choice(["brown", "grey"])),
                  sky=str(rng.choice(["blue", "overcast"])), jpeg_quality=int(rng.choice([0, 70, 90])))
    if form == "conifer":
        return st.config_for("conifer", **common, trunk_frac=float(rng.uniform(0.1, 0.3)),
                             cluster_radius_px=float(rng.uniform(5.0, 9.0))), form
    if form == "palm":
        return st.config_for("palm", **common, fronds=(int(rng.integers(6, 10)), int(rng.integers(10, 16)))), form
    if form == "dense":
        return st.config_for("dense", **common, fill_clusters=int(rng.integers(10, 60)),
                             cluster_radius_px=float(rng.uniform(9.0, 16.0))), form
    tree = dict(max_order=int(rng.integers(3, 6)), children=(2, int(rng.integers(2, 4))),
                branch_angle_deg=(float(rng.uniform(15, 30)), float(rng.uniform(35, 65))),
                length_ratio=(float(rng.uniform(0.5, 0.65)), float(rng.uniform(0.7, 0.85))),
                trunk_frac=float(rng.uniform(0.2, 0.5)))
    if form == "sparse":
        return st.config_for("sparse", **common, **tree), form
    if form == "young":                       # a nearly planar young tree, few orders, little foliage
        tree.update(max_order=int(rng.integers(2, 4)), branch_angle_deg=(10.0, float(rng.uniform(20, 35))))
        return st.config_for("broad", **common, **tree, cluster_prob=0.2, leaves_per_cluster=10), form
    if form == "bare":
        return st.config_for("broad", **common, **tree, cluster_prob=0.0, tip_cluster_prob=0.0), form
    return st.config_for("broad", **common, **tree, cluster_prob=float(rng.uniform(0.2, 0.7)),
                         leaves_per_cluster=int(rng.integers(14, 36)), cluster_radius_px=float(rng.uniform(6, 12))), form


def _leaf_world(scene: st.Scene) -> np.ndarray:
    """Leaf centres ``(Lv, 3)`` world px at frame 1."""
    lv = scene.leaves
    if len(lv.rest) == 0:
        return np.zeros((0, 3))
    A = scene.motion.A[:, 0][lv.branch]
    t = scene.motion.t[:, 0][lv.branch]
    return np.einsum("lij,lj->li", A, lv.rest) + t


def traced_like(scene: st.Scene, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The true skeleton as a trace gives it: ``(nodes2d (N', 2) px, parents (N',))``: nodes jittered
    ~1 px, a share of the last order's branches (their whole subtrees) dropped."""
    tree = scene.tree
    P = st.project(scene, scene.nodes3d[0]) + rng.normal(0.0, 0.8, (len(tree.parents), 2))
    last = tree.depth_level.max()
    drop_branch = (tree.branch_depth == last) & (rng.random(len(tree.branch_depth)) < rng.uniform(0.0, 0.5))
    keep = ~drop_branch[tree.node_branch]
    keep[tree.parents < 0] = True
    # a dropped node's descendants go too (they hang from it)
    keep &= ld.ancestor_sums(tree.parents, ~keep) == 0
    idx = np.full(len(keep), -1)
    idx[keep] = np.arange(keep.sum())
    par = tree.parents[keep]
    return P[keep], np.where(par >= 0, idx[np.maximum(par, 0)], -1)


def sample(seed: int, size: int = ld.SIZE) -> dict:
    """The training pair of tree ``seed`` (module docstring)."""
    cfg, form = config(seed)
    scene = st.build_scene(cfg)
    rng = np.random.default_rng([36, seed])
    frame = st.render_frame(scene, 0)
    gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    labels = st.render_labels(scene, 0, foreground=False)
    sil = (labels == st.LABEL_BRANCH) | (labels == st.LABEL_LEAF)
    poly = st.outline_polygon(cfg, sil)
    mask = np.zeros(gray.shape, np.uint8)
    cv2.fillPoly(mask, [np.rint(poly).astype(np.int32)], 1)
    mask = mask > 0
    nodes2d, parents = traced_like(scene, rng)
    x, box = ld.encode(gray, mask, nodes2d, parents, size=size)
    H = ld.tree_height_px(mask)
    tree = scene.tree
    root = int(np.nonzero(tree.parents < 0)[0][0])
    y_root = scene.nodes3d[0][root, 1]
    depth = (scene.nodes3d[0][:, 1] - y_root) / H
    # skeleton depth on the drawn skeleton (its own jittered nodes): the front-most where branches cross
    P = st.project(scene, scene.nodes3d[0])
    child = np.nonzero(tree.parents >= 0)[0]
    pc = box.to_crop(P, size)
    pts, seg, t = ld.segment_samples(pc[tree.parents[child]], pc[child])
    d_seg = depth[tree.parents[child]][seg] + (depth[child][seg] - depth[tree.parents[child]][seg]) * t
    y = np.zeros((ld.OUT_CHANNELS, size, size), np.float32)
    w = np.zeros((ld.OUT_CHANNELS, size, size), bool)
    sk_front = ld.splat(pts, d_seg, size, "min", fill=np.nan)
    drawn = x[2] > 0
    # the drawn (jittered) skeleton's pixels take the nearest true depth within a pixel
    near = cv2.dilate(np.nan_to_num(-sk_front, nan=-np.inf).astype(np.float32), np.ones((3, 3), np.uint8))
    have = np.isfinite(near) & drawn
    y[0][have] = ld.to_unit(-near[have])
    w[0] = have
    # the tree's dual depth: leaves (centres and card corners) and branches
    leaves = _leaf_world(scene)
    lp = st.leaf_polygons(scene, 0) if len(leaves) else np.zeros((0, 6, 2))
    ld_ = (leaves[:, 1] - y_root) / H if len(leaves) else np.zeros(0)
    lc = st.project(scene, leaves) if len(leaves) else np.zeros((0, 2))
    all_pts = np.concatenate([pts, box.to_crop(lc, size), box.to_crop(lp.reshape(-1, 2), size),
                              box.to_crop((lp + lc[:, None]).reshape(-1, 2) * 0.5, size)])
    all_d = np.concatenate([d_seg, ld_, np.repeat(ld_, 6), np.repeat(ld_, 6)])
    front = ld.splat(all_pts, all_d, size, "min", fill=np.nan)
    back = ld.splat(all_pts, all_d, size, "max", fill=np.nan)
    cover = np.isfinite(front)
    y[1][cover] = ld.to_unit(front[cover])
    y[2][cover] = np.clip(back[cover] - front[cover], 0.0, 1.0)
    w[1] = w[2] = cover
    return dict(x=(x * 255).astype(np.uint8), y=y, w=w, form=form, seed=seed)


def magnitudes(y: np.ndarray) -> np.ndarray:
    """The generated targets (unit signed depths: skeleton, crown front; the interval) → what the
    network learns, free of the sign one view cannot tell (in front of the trunk's plane or behind
    it is a coin toss: an L1 fit of signed depths sinks to 0, measured: the crown's predicted depths
    spanned ±0.05 H where the true ones spanned ±0.4 H): the skeleton's distance from the plane
    |d| / H, the crown's reach max(|front|, |back|) / H, and the interval / H."""
    d = ld.from_unit(y[:, 0])
    front = ld.from_unit(y[:, 1])
    back = front + y[:, 2]
    out = np.stack([np.abs(d), np.maximum(np.abs(front), np.abs(back)), y[:, 2]], 1)
    return np.clip(out, 0.0, 1.0).astype(np.float32)


def build(seeds: range, progress: bool = True) -> dict:
    """Stacked pairs of ``seeds``: ``x (T, C, S, S)`` uint8, ``y`` float16, ``w`` bool, ``form``, ``seed``."""
    out: dict = {k: [] for k in ("x", "y", "w", "form", "seed")}
    for k, s in enumerate(seeds):
        d = sample(s)
        for key in out:
            out[key].append(d[key])
        if progress and (k + 1) % 50 == 0:
            print(f"  {k + 1}/{len(seeds)} trees", flush=True)
    return {"x": np.stack(out["x"]), "y": np.stack(out["y"]).astype(np.float16), "w": np.stack(out["w"]),
            "form": np.array(out["form"]), "seed": np.array(out["seed"])}


def cached(path: str, seeds: range) -> dict:
    """:func:`build` of ``seeds``, kept in ``path`` (.npz) and read back when its seeds match."""
    if os.path.isfile(path):
        with np.load(path) as z:
            if list(z["seed"]) == list(seeds):
                return {k: z[k] for k in z.files}
    data = build(seeds)
    tmp = path + ".tmp.npz"
    np.savez_compressed(tmp, **data)
    os.replace(tmp, path)
    return data


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="0:8")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    a, b = (int(v) for v in args.seeds.split(":"))
    data = build(range(a, b))
    np.savez_compressed(args.out, **data)
    print(f"{b - a} pairs -> {args.out}: forms {dict(zip(*np.unique(data['form'], return_counts=True)))}")


if __name__ == "__main__":
    main()
