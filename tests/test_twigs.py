"""Twigs by self-similarity (core/twigs.py): counts per depth, inside the envelope, angle and length
ratios of the tree's own forks, motion riding on the parent bone with the given lag and attenuation,
no zero-length bones; and the twig bones in FBX / glTF exports, animated (read back)."""
import math

import numpy as np
import pytest

from tree_from_video.core import bones, rotations
from tree_from_video.core.detail import twigs as tw
from tree_from_video.core.envelope import Envelope, envelope_from_meta, envelope_to_meta
from tree_from_video.core.errors import InputError
from tree_from_video.core.tree3d import Tree3D

from trees import binary_tree, broad_tree

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]


@pytest.fixture(scope="module")
def broad():
    return broad_tree(None)                     # 180 frames: enough sway for the lag test


def _with_envelope(tree: Tree3D, margin: float) -> Tree3D:
    """``tree`` with a crown envelope hugging its frame-0 nodes: per 0.25 m of height, the largest
    horizontal distance of a node from the trunk axis, plus ``margin`` metres."""
    rest = tree.nodes3d[0].astype(float)
    z = np.arange(-0.25, rest[:, 2].max() + 0.5, 0.25)
    r = np.array([np.hypot(rest[:, 0], rest[:, 1])[np.abs(rest[:, 2] - h) < 0.5].max(initial=0.0) for h in z])
    env = Envelope(z, np.zeros_like(z), r + margin)
    meta = dict(tree.meta, envelope=envelope_to_meta(env, 1.0))
    return Tree3D(tree.parents, tree.nodes3d, tree.radius, tree.level, tree.fps, tree.name, meta)


def _tips(parents):
    n_child = np.bincount(parents[parents >= 0], minlength=len(parents))
    return np.flatnonzero((n_child == 0) & (parents >= 0))


# ----------------------------------------------------------------------------- formulas by hand

def test_slerp_to_rest_and_lag_by_hand():
    q90 = np.array([math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)])           # 90° about z
    np.testing.assert_allclose(tw.slerp_to_rest(q90, 0.5),
                               [math.cos(math.pi / 8), 0, 0, math.sin(math.pi / 8)], atol=1e-12)   # 45°
    np.testing.assert_allclose(tw.slerp_to_rest(q90, 0.0), q90, atol=1e-12)
    np.testing.assert_allclose(tw.slerp_to_rest(-q90, 1.0), [1, 0, 0, 0], atol=1e-12)
    # frames t use the driver's frame t − lag (frame 0 before that)
    angles = np.arange(6) * 0.1
    q = np.stack([np.cos(angles / 2), 0 * angles, 0 * angles, np.sin(angles / 2)], -1)[:, None]
    got = tw.twig_rotations(q, lag=2, attenuation=0.0)[:, 0]
    np.testing.assert_allclose(2 * np.arctan2(got[:, 3], got[:, 0]), [0, 0, 0, 0.1, 0.2, 0.3], atol=1e-12)


def test_templates_of_a_fork_by_hand():
    # trunk 0→1 up (2 m); fork at 1: child 2 along +x·sin30 + z·cos30 (1 m), child 3 along −x (0.5 m)
    parents = np.array([-1, 0, 1, 1])
    pos = np.array([[0, 0, 0], [0, 0, 2.0], [0.5, 0, 2 + math.sqrt(3) / 2], [-0.5, 0, 2.0]])
    t = tw.measure_templates(parents, pos)
    assert t.n == 1 and t.fork.tolist() == [1] and t.count.tolist() == [2]
    np.testing.assert_allclose(np.degrees(t.theta), [30, 90], atol=1e-9)
    np.testing.assert_allclose(t.rho, [0.5, 0.25], atol=1e-12)
    # trunk is vertical: azimuths from world +x; child 2 at 0, child 3 at 180°
    np.testing.assert_allclose(np.abs(t.phi), [0, math.pi], atol=1e-9)


# ----------------------------------------------------------------------------- growth

def test_depth_zero_is_the_same_tree_and_counts_follow_depth():
    tree = binary_tree(n_bones=31, frames=20)
    assert tw.add_twigs(tree, tw.TwigParams(depth=0)) is tree
    T = len(_tips(tree.parents))                                                     # 16 tips
    for d in (1, 2, 3):
        out = tw.add_twigs(tree, tw.TwigParams(depth=d))
        # every binary-tree fork has 2 children: 2 + 4 + … + 2^d twigs per tip
        assert out.meta["twigs"]["nodes_added"] == out.n_nodes - tree.n_nodes == T * (2 ** (d + 1) - 2)
        assert out.meta["twigs"]["per_generation"] == [T * 2 ** g for g in range(1, d + 1)]
        np.testing.assert_array_equal(out.parents[:tree.n_nodes], tree.parents)        # originals kept
        np.testing.assert_array_equal(out.nodes3d[:, :tree.n_nodes], tree.nodes3d)
        assert bones.bone_names(out.parents)[:tree.n_nodes - 1] == bones.bone_names(tree.parents)
        assert (out.parents[tree.n_nodes:] < np.arange(tree.n_nodes, out.n_nodes)).all()   # parents first
    capped = tw.add_twigs(tree, tw.TwigParams(depth=3, max_nodes=50))
    assert capped.n_nodes - tree.n_nodes == 50


def test_twigs_stay_inside_the_envelope_at_frame_0(broad):
    tree = _with_envelope(broad, margin=0.3)
    env = envelope_from_meta(tree.meta)
    out = tw.add_twigs(tree, tw.TwigParams(depth=3, seed=1))
    N = tree.n_nodes
    rest = out.nodes3d[0].astype(float)
    inside = env.contains(rest[N:], tol=1e-6)
    assert inside.all(), f"{(~inside).sum()} of {len(inside)} twig nodes outside"
    # every twig bone along its length too (the four probe points)
    a, b = rest[out.parents[N:]], rest[N:]
    for f in tw.PROBES:
        assert env.contains(a + f * (b - a), tol=1e-6).all()
    info = out.meta["twigs"]
    assert info["rejected"] > 0 and info["shrunk"] > 0, "the envelope never constrained the twigs"
    free = tw.add_twigs(broad, tw.TwigParams(depth=3, seed=1))
    outside = ~env.contains(free.nodes3d[0, N:].astype(float), tol=1e-6)
    assert outside.any(), "the test envelope is too loose to show anything"
    print(f"\nenvelope: {len(inside)} twig nodes inside, {info['rejected']} twigs dropped, {info['shrunk']} shrunk "
          f"(without the envelope {outside.sum()} of {len(outside)} would be outside)")


def _twig_angles_and_ratios(tree, out):
    """θ (angle to the parent direction) and ρ (length ÷ parent length) of every twig, measured
    the way the templates are: parent = the tip bone's direction and tip chain's chord for
    generation 1, the parent twig bone for later generations."""
    from tree_from_video.core.topology import chains
    N = tree.n_nodes
    rest = out.nodes3d[0].astype(np.float64)
    par = out.parents.astype(int)
    n_child = np.bincount(tree.parents[tree.parents >= 0], minlength=N)
    ch = chains(tree.parents, rest[:N], (tree.parents < 0) | (n_child != 1))
    twig = np.arange(N, out.n_nodes)
    a = par[twig]
    e = rest[a] - rest[par[a]]
    last = np.linalg.norm(e, axis=1)
    e /= last[:, None]
    L = np.where(a < N, np.maximum(np.linalg.norm(rest[a] - rest[np.maximum(ch.up[np.minimum(a, N - 1)], 0)], axis=1),
                                   last), last)
    c = rest[twig] - rest[a]
    clen = np.linalg.norm(c, axis=1)
    theta = np.arccos(np.clip(np.sum(c * e, axis=1) / clen, -1, 1))
    return theta, clen / L


def test_angles_and_length_ratios_follow_the_source_forks(broad):
    out = tw.add_twigs(broad, tw.TwigParams(depth=2, seed=4))                  # no envelope: no shrinking
    tpl = tw.measure_templates(broad.parents, broad.nodes3d[0])
    theta, rho = _twig_angles_and_ratios(broad, out)
    # every twig is one of the tree's own fork children, to float32 precision
    d = np.hypot(theta[:, None] - tpl.theta[None], rho[:, None] - tpl.rho[None]).min(axis=1)
    assert d.max() < 2e-3, f"a twig matches no source bifurcation (off by {d.max():.4f})"
    # and their distribution is that of the source forks (templates drawn uniformly)
    w = np.repeat(1.0 / tpl.count, tpl.count) / tpl.n                            # each child's probability
    for x, src in ((theta, tpl.theta), (rho, tpl.rho)):
        assert np.mean(x) == pytest.approx(np.sum(w * src), rel=0.08)
        grid = np.sort(np.concatenate([x, src]))
        cdf_twig = np.searchsorted(np.sort(x), grid, side="right") / len(x)
        order = np.argsort(src)
        cdf_src = np.concatenate([[0], np.cumsum(w[order])])[np.searchsorted(src[order], grid, side="right")]
        assert np.abs(cdf_twig - cdf_src).max() < 0.12                          # Kolmogorov–Smirnov distance
    print(f"\n{len(theta)} twigs from {tpl.n} forks: mean angle {np.degrees(theta.mean()):.1f}° "
          f"(forks {np.degrees(np.sum(w * tpl.theta)):.1f}°), mean length ratio {rho.mean():.3f} "
          f"(forks {np.sum(w * tpl.rho):.3f})")


def test_no_zero_length_bones_and_thinner_twigs(broad):
    out = tw.add_twigs(_with_envelope(broad, 0.3), tw.TwigParams(depth=3, seed=2))
    N = broad.n_nodes
    bones.check_positions(out.parents, out.nodes3d)                                 # raises on a zero-length bone
    length = np.linalg.norm(out.nodes3d[:, N:] - out.nodes3d[:, out.parents[N:]], axis=-1)
    height = float(np.ptp(broad.nodes3d[0], axis=0).max())
    assert length.min() >= 0.99 * 1e-3 * height
    np.testing.assert_allclose(length, length[:1].repeat(len(length), 0), rtol=1e-4)   # rigid: lengths kept
    assert (out.radius[N:] < out.radius[out.parents[N:]]).all()
    assert (out.level[N:] == out.level[out.parents[N:]] + 1).all()
    # a tree whose twigs would all be shorter than min_length gets none (and no error)
    none = tw.add_twigs(broad, tw.TwigParams(depth=2, min_length=0.5))
    assert none.n_nodes == N and none.meta["twigs"]["nodes_added"] == 0
    with pytest.raises(InputError, match="attenuation"):
        tw.add_twigs(broad, tw.TwigParams(depth=1, attenuation=1.5))


@pytest.mark.parametrize("lag,att", [(0, 0.0), (3, 0.25), (6, 0.5)])
def test_twig_motion_follows_the_parent_bone_with_lag_and_attenuation(broad, lag, att):
    out = tw.add_twigs(broad, tw.TwigParams(depth=2, seed=0, lag_frames=lag, attenuation=att))
    N = broad.n_nodes
    q = bones.world_rotations(broad.parents, broad.nodes3d)                         # the driver bones
    bone_of_node = {int(c): i for i, c in enumerate(bones.bone_edges(broad.parents)[:, 1])}
    twig = np.flatnonzero(out.parents[N:] < N) + N                               # generation 1
    a = out.parents[twig]
    x = out.nodes3d.astype(np.float64)
    rel = x[:, twig] - x[:, a]                                                   # twig vector per frame
    rigid = rotations.quat_rotate(q[:, [bone_of_node[int(n)] for n in a]], rel[0][None])  # riding without lag
    sway_twig = (rel - rel[:1]).reshape(len(x), -1)
    sway_parent = (rigid - rel[:1]).reshape(len(x), -1)
    F = len(x)
    corr = []
    for s in range(0, 11):                                                       # twig(t) vs parent(t − s)
        a_, b_ = sway_twig[s + 10:], sway_parent[10:F - s]
        corr.append(np.sum(a_ * b_) / np.sqrt(np.sum(a_ * a_) * np.sum(b_ * b_)))
    best = int(np.argmax(corr))
    amp = np.linalg.norm(sway_twig[lag + 10:]) / np.linalg.norm(sway_parent[10:F - lag])
    print(f"\nlag {lag}, attenuation {att}: measured lag {best} frames, correlation {corr[best]:.3f}, "
          f"amplitude ratio {amp:.3f}")
    assert best == lag
    assert corr[best] > 0.98
    assert amp == pytest.approx(1 - att, rel=0.05)
    # the twig stays glued to the tip it grows from, and the whole twig moves as one rigid shape
    sub = np.arange(N, out.n_nodes)
    d0 = np.linalg.norm(x[0, sub][:, None] - x[0, sub][None], axis=-1)
    dt = np.linalg.norm(x[90, sub][:, None] - x[90, sub][None], axis=-1)
    same_root = np.equal.outer(_root_tip(out, N)[sub - N], _root_tip(out, N)[sub - N])
    assert np.abs(dt - d0)[same_root].max() < 1e-4


def _root_tip(out, N):
    """The reconstructed tip each twig node grows from."""
    root = out.parents.astype(int).copy()
    for _ in range(10):
        root = np.where(root >= N, out.parents[np.maximum(root, 0)], root)
    return root[N:]


# ----------------------------------------------------------------------------- pipeline and batch

def test_pipeline_adds_twigs_after_the_motion_inside_the_envelope():
    """The reconstruction of 30 frames of the committed sample with and without twigs: the same
    reconstructed nodes, twigs appended inside the solver's envelope, the mesh settings in meta."""
    import os

    from tree_from_video.core import pipeline

    from samples import plain_settings
    from trees import ROOT
    folder = os.path.join(ROOT, "sample_videos", "broad")
    s = plain_settings(frames="0:30")
    s.leaves = None
    res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
    bare = pipeline.build_3d(res, s)
    s.twigs = tw.TwigParams(depth=2, seed=1)
    s.curliness, s.bark = 0.4, "rough"
    twiggy = pipeline.build_3d(res, s)
    N = bare.n_nodes
    assert "twigs" not in bare.meta and bare.meta["mesh"] == {"curliness": 0.0, "bark": "none", "seed": 0,
                                                             "forks": "joined", "relief_cm": 0.0}
    assert twiggy.meta["mesh"] == {"curliness": 0.4, "bark": "rough", "seed": 1, "forks": "joined", "relief_cm": 0.0}
    np.testing.assert_array_equal(twiggy.nodes3d[:, :N], bare.nodes3d)
    added = twiggy.meta["twigs"]["nodes_added"]
    assert added == twiggy.n_nodes - N > N // 4
    env = envelope_from_meta(twiggy.meta)
    assert env.contains(twiggy.nodes3d[0, N:].astype(float), tol=1e-6).all()
    bones.check_positions(twiggy.parents, twiggy.nodes3d)
    with pytest.raises(InputError, match="twig depth"):
        s.twigs.depth = 9
        pipeline.check_settings(s)
    print(f"\nbroad sample, 30 frames: {N} reconstructed nodes + {added} twig nodes "
          f"({twiggy.meta['twigs']['per_generation']}, {twiggy.meta['twigs']['rejected']} dropped at the envelope)")


def test_batch_flags_reach_the_settings(tmp_path):
    from tree_from_video import cli as batch
    args = batch.build_parser().parse_args(["v.mp4", "--outline", "o.json", "--out", "x", "--twigs", "2",
                                            "--curliness", "0.5", "--bark", "smooth"])
    assert (args.twigs, args.curliness, args.bark) == (2, 0.5, "smooth")
    defaults = batch.build_parser().parse_args(["v.mp4", "--outline", "o.json", "--out", "x"])
    assert (defaults.twigs, defaults.curliness, defaults.bark) == (2, 0.3, "rough")   # as the panel
    for bad in (["--twigs", "9"], ["--curliness", "2"]):
        out = tmp_path / "out"
        assert batch.main(["missing.mp4", "--outline", "o.json", "--out", str(out), *bad]) == 2
        assert not out.exists()


# ----------------------------------------------------------------------------- exports with twigs

@pytest.fixture
def blender():
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)


@pytest.fixture(scope="module")
def twiggy():
    tree = broad_tree(24)
    return tw.add_twigs(tree, tw.TwigParams(depth=2, seed=3, lag_frames=2)), tree.n_nodes


def test_fbx_with_twigs_reimports_their_bones_animated(blender, twiggy, tmp_path):
    """FBX stores joints, not tails: a re-imported bone without children gets a guessed length, so
    heads and directions are compared (generation-2 heads are generation-1 tails)."""
    from tree_from_video.operators.scene import build, export

    from trees import played, pose_heads_dirs, tree_height
    tree, N = twiggy
    built = build.build_tree(blender.context, tree, "Tree", curliness=0.5, bark="rough")
    twig_names = [f"B{c:03d}" for c in range(N, tree.n_nodes)]
    want = played(built["armature"], twig_names, (1, 12, 24))      # what the rig's curves play
    path = export.export_fbx(tmp_path / "tree.fbx", [built["armature"], built["mesh"]])
    blender.ops.wm.read_factory_settings(use_empty=True)
    blender.ops.import_scene.fbx(filepath=str(path))
    rig = [ob for ob in blender.context.scene.objects if ob.type == "ARMATURE"][0]
    names = bones.bone_names(tree.parents)
    assert set(twig_names) <= {b.name for b in rig.data.bones} and len(rig.data.bones) == len(names)
    tol = 1e-4 * tree_height(tree)
    moved = 0.0
    for k in (1, 12, 24):
        blender.context.scene.frame_set(k)
        heads, dirs = pose_heads_dirs(rig, twig_names)
        want_heads, _, want_dirs = want[k]
        assert np.abs(heads - want_heads).max() <= tol, f"frame {k}: twig heads off"
        assert np.abs(dirs - want_dirs).max() <= 1e-4, f"frame {k}: twig directions off"
        if k == 1:
            first = dirs
        moved = max(moved, np.abs(dirs - first).max())
    assert moved > 0.01, "the twigs do not turn in the re-imported file"
    print(f"\nFBX: {len(twig_names)} twig bones re-imported, heads within {tol:.1e} m, "
          f"directions within 1e-4, turning by up to {moved:.3f}")


def test_gltf_with_twigs_has_their_joints_and_rotation_keys(blender, twiggy, tmp_path):
    from test_exports import accessor, read_glb

    from tree_from_video.operators.scene import build, export
    tree, N = twiggy
    built = build.build_tree(blender.context, tree, "Tree")
    path = export.export_gltf(tmp_path / "tree.glb", [built["armature"], built["mesh"]])
    doc, binary = read_glb(path)
    joints = doc["skins"][0]["joints"]
    by_name = {doc["nodes"][j]["name"]: j for j in joints}
    twig_names = [f"B{c:03d}" for c in range(N, tree.n_nodes)]
    assert set(twig_names) <= set(by_name)
    anim = doc["animations"][0]
    rot = {c["target"]["node"]: anim["samplers"][c["sampler"]] for c in anim["channels"]
           if c["target"]["path"] == "rotation"}
    varying = 0
    for n in twig_names:
        sampler = rot[by_name[n]]
        q = accessor(doc, binary, sampler["output"])
        assert q.shape == (tree.n_frames, 4)
        varying += np.ptp(q, axis=0).max() > 1e-4
    assert varying >= 0.8 * len(twig_names), f"only {varying} of {len(twig_names)} twig bones are animated"
    mesh_skin = [m for m in doc["meshes"]]
    assert len(mesh_skin) == 1
    print(f"\nglTF: {len(twig_names)} twig joints, {varying} with varying rotation keys")


def test_twigs_stay_over_the_trees_pixels_in_frame_1(broad):
    """With frame 1's tree pixels, a twig lies over them (grown by TREE_PX_MARGIN): here the
    "video" shows the tree only left of the trunk, so no twig reaches to the right of it."""
    rest = broad.nodes3d[0].astype(float)
    m = 0.02                                              # metres per px
    W, H = 1200, 800
    base = (600.0, 700.0)
    meta = dict(broad.meta, base_px=list(base), metres_per_px=m)
    tree = Tree3D(broad.parents, broad.nodes3d, broad.radius, broad.level, broad.fps, broad.name, meta)
    tree_px = np.zeros((H, W), bool)
    tree_px[:, :600] = True                               # x < base: left of the trunk
    out = tw.add_twigs(tree, tw.TwigParams(depth=2, seed=3), tree_px=tree_px)
    N = tree.n_nodes
    pts = out.nodes3d[0, N:].astype(float)
    x_px = base[0] + pts[:, 0] / m
    assert len(pts) > 0 and (x_px <= 600 + tw.TREE_PX_MARGIN + 0.5).all()
    free = tw.add_twigs(tree, tw.TwigParams(depth=2, seed=3))
    right = (base[0] + free.nodes3d[0, N:, 0].astype(float) / m > 600 + tw.TREE_PX_MARGIN + 0.5).sum()
    assert right > 0 and (rest[:, 0] > 0).any()           # without the pixels, twigs do grow on the right
    print(f"\ntree pixels: {len(pts)} twig nodes, all left of the trunk (without them {right} on the right)")
