"""The branch mesh (core/branch_mesh.py) by hand — straight tubes, minimum-jerk curliness, seamless
bark rings, UVs continuous along branches — and as built in Blender (vertex count, weights, closed
surface, timing of a ~400-bone tree)."""
import time

import bpy
import numpy as np
import pytest

from tree_from_video.core import bones
from tree_from_video.core.asset.meshes import branch_arrays
from tree_from_video.core.detail import branch_mesh as bm
from tree_from_video.core.detail.shapes import BARK_PRESETS
from tree_from_video.core.errors import InputError
from tree_from_video.operators.scene import branch_mesh as scene_mesh
from tree_from_video.operators.scene import build, materials

from trees import (
    assert_closed_tubes,
    binary_tree,
    broad_tree,
    empty_scene,  # noqa: F401  (autouse fixture)
    rig_rest,
)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]


@pytest.fixture(scope="module")
def tree():
    return broad_tree(40)


def _geometry(tree, **kw):
    rest = bones.rest_frames(tree.parents, tree.nodes3d[0])
    r_head, r_tail = bm.branch_radii(tree.parents, tree.radius)
    sides = kw.pop("sides", 8)
    return rest, r_head, r_tail, bm.tube_arrays(tree.nodes3d[0], tree.parents, rest, r_head, r_tail, sides, **kw)


def _line_distance(p, a, d):
    """Distance of points ``p (..., 3)`` to the lines through ``a`` along unit ``d``."""
    w = p - a
    return np.linalg.norm(w - np.sum(w * d, axis=-1, keepdims=True) * d, axis=-1)


# ----------------------------------------------------------------------------- straight tubes

def test_three_sided_tube_by_hand():
    # one vertical bone 0→1 (2 m), then a child 1→2 along +x (1 m); radii 0.2 → 0.1 → 0.05
    parents = np.array([-1, 0, 1])
    pos = np.array([[0, 0, 0], [0, 0, 2.0], [1, 0, 2.0]])
    rest = bones.rest_frames(parents, pos)
    g = bm.tube_arrays(pos, parents, rest, np.array([0.2, 0.1]), np.array([0.1, 0.05]), 3)
    S, K = 3, 2
    assert len(g["co"]) == K * S * 2 and len(g["loop_start"]) == ((K - 1) * S + 2) * 2
    # bone 0: quads (ring 0 → ring 1), head cap ascending, tail cap descending
    assert g["loop_vert"][:18].tolist() == [0, 3, 4, 1, 1, 4, 5, 2, 2, 5, 3, 0, 0, 1, 2, 5, 4, 3]
    assert g["loop_vert"][18:21].tolist() == [6, 9, 10]
    # bone 0's rest X is +x, Z is −y: vertex k at (r cos θk, −r sin θk, z)
    th = 2 * np.pi * np.arange(3) / 3
    np.testing.assert_allclose(g["co"][:3], np.stack([0.2 * np.cos(th), -0.2 * np.sin(th), 0 * th], 1), atol=1e-12)
    np.testing.assert_allclose(g["co"][3:6, 2], 2.0)
    # bone 1 starts ext = r_head = 0.1 before its head (inside the trunk), along its own axis (+x)
    np.testing.assert_allclose(g["centre"][1, 0], [-0.1, 0, 2.0], atol=1e-12)
    assert g["tau"][1, 0] == pytest.approx(-0.1)
    # v: arc length ÷ (2π · thickest head radius); child head at arc 2 m, its ring 0 at 1.9 m
    tile = 2 * np.pi * 0.2
    np.testing.assert_allclose(g["v"], [[0, 2 / tile], [1.9 / tile, 3 / tile]], atol=1e-12)


def test_curliness_zero_gives_straight_tubes_on_the_bones(tree):
    rest, r_head, r_tail, g = _geometry(tree)
    edges = tree.edges()
    B, S = len(edges), 8
    assert g["rings"] == 2 and len(g["co"]) == 2 * S * B
    head, tail = tree.nodes3d[0][edges[:, 0]].astype(float), tree.nodes3d[0][edges[:, 1]].astype(float)
    d = (tail - head) / np.linalg.norm(tail - head, axis=1, keepdims=True)
    co = g["co"].reshape(B, 2, S, 3)
    dist = _line_distance(co, head[:, None, None], d[:, None, None])
    np.testing.assert_allclose(dist[:, 0], np.repeat(r_head[:, None], S, 1), rtol=1e-9)
    np.testing.assert_allclose(dist[:, 1], np.repeat(r_tail[:, None], S, 1), rtol=1e-9)
    np.testing.assert_allclose(co[:, 1].mean(axis=1), tail, atol=1e-9)        # tail ring around the tail


# ----------------------------------------------------------------------------- curliness

def test_minimum_jerk_offset_by_hand():
    parents = np.array([-1, 0])
    pos = np.array([[0, 0, 0], [0, 0, 4.0]])
    rest = bones.rest_frames(parents, pos)
    g = bm.tube_arrays(pos, parents, rest, np.array([0.1]), np.array([0.1]), 8, curliness=1.0, rings=5, seed=3)
    o = bm.curl_offsets(rest, np.array([4.0]), 1.0, 3)[0]
    assert 0.5 * bm.CURL_SHARE * 4 <= np.linalg.norm(o) <= bm.CURL_SHARE * 4
    assert abs(o[2]) < 1e-12                                                 # perpendicular to the bone
    # τ = 0.25: s = 0.25³ (10 − 3.75 + 0.375) = 0.103515625, bump = 4 s (1 − s) = 0.37120819...
    s = 0.103515625
    np.testing.assert_allclose(g["centre"][0, 1], [0, 0, 1.0] + 4 * s * (1 - s) * o, atol=1e-12)
    np.testing.assert_allclose(g["centre"][0, 2], [0, 0, 2.0] + o, atol=1e-12)       # full offset mid-bone
    np.testing.assert_allclose(g["centre"][0, [0, 4]], pos, atol=1e-12)              # ends on the bone
    np.testing.assert_allclose(g["tangent"][0, [0, 4]], [[0, 0, 1], [0, 0, 1]], atol=1e-12)
    # the ring vertices are around the curve (ring centre = mean of its vertices without bark)
    np.testing.assert_allclose(g["co"].reshape(5, 8, 3).mean(axis=1), g["centre"][0], atol=1e-12)


def test_curliness_one_is_bounded_smooth_at_joints_and_seeded(tree):
    rest, r_head, r_tail, g = _geometry(tree, curliness=1.0)
    edges = tree.edges()
    B, K, S = len(edges), g["rings"], 8
    head, tail = tree.nodes3d[0][edges[:, 0]].astype(float), tree.nodes3d[0][edges[:, 1]].astype(float)
    length = np.linalg.norm(tail - head, axis=1)
    d = (tail - head) / length[:, None]
    centres = g["co"].reshape(B, K, S, 3).mean(axis=2)                        # from the mesh itself
    lateral = _line_distance(centres, head[:, None], d[:, None])
    assert (lateral <= bm.CURL_SHARE * length[:, None] + 1e-9).all()
    ratio = lateral.max(axis=1) / length
    assert np.median(ratio) > 0.5 * bm.CURL_SHARE * 0.9, "curliness 1 barely bends the tubes"
    print(f"\ncurliness 1: lateral offset median {np.median(ratio):.3f}, max {ratio.max():.3f} of the bone length")
    # joints: the first and last rings are perpendicular to the straight bone (no added kink)
    np.testing.assert_allclose(np.sum(g["tangent"][:, [0, -1]] * d[:, None], axis=-1), 1.0, atol=1e-9)
    np.testing.assert_allclose(g["centre"][:, -1], tail, atol=1e-9)
    # the same seed gives the same mesh, another seed another one
    _, _, _, g2 = _geometry(tree, curliness=1.0)
    _, _, _, g3 = _geometry(tree, curliness=1.0, seed=1)
    assert np.array_equal(g["co"], g2["co"]) and np.abs(g["co"] - g3["co"]).max() > 1e-3
    half = _geometry(tree, curliness=0.5)[3]
    lat_half = _line_distance(half["centre"], head[:, None], d[:, None]).max(axis=1)
    np.testing.assert_allclose(lat_half, 0.5 * lateral.max(axis=1), rtol=1e-6, atol=1e-12)


# ----------------------------------------------------------------------------- bark

@pytest.mark.parametrize("kind", ["smooth", "rough"])
def test_bark_rings_close_and_stay_within_the_preset(tree, kind):
    S = 32
    rest, r_head, r_tail, g = _geometry(tree, sides=S, bark=kind, seed=5)
    edges = tree.edges()
    B, K = len(edges), g["rings"]
    head, tail = tree.nodes3d[0][edges[:, 0]].astype(float), tree.nodes3d[0][edges[:, 1]].astype(float)
    d = (tail - head) / np.linalg.norm(tail - head, axis=1, keepdims=True)
    r = _line_distance(g["co"].reshape(B, K, S, 3), head[:, None, None], d[:, None, None])   # actual vertices
    rel = r / g["r0"][..., None] - 1.0
    lo, hi = BARK_PRESETS[kind]
    amp, freqs, phases, drift = g["bark"]
    assert np.all(freqs == np.round(freqs)) and freqs.max() < S / 2
    assert np.abs(rel).max() <= hi + 1e-9 and np.abs(rel).max() <= amp.sum() + 1e-9
    assert np.abs(rel).max() >= 0.5 * amp.sum() and amp.sum() >= lo
    # the formula r0 (1 + Σ b sin(ω θ + φ + drift·v)) at every vertex, and at θ = 2π it equals θ = 0
    theta = 2 * np.pi * np.arange(S) / S
    ph = phases + drift * g["v"][..., None]                                               # (B, K, T)
    want = np.sum(amp * np.sin(freqs * theta[:, None, None, None] + ph), axis=-1)         # (S, B, K)
    np.testing.assert_allclose(rel, np.moveaxis(want, 0, -1), atol=1e-9)
    at_2pi = np.sum(amp * np.sin(freqs * 2 * np.pi + ph), axis=-1)
    np.testing.assert_allclose(at_2pi, rel[..., 0], atol=1e-9)                            # closes at the seam
    steps = np.abs(np.diff(rel, axis=-1)).max()
    seam = np.abs(rel[..., -1] - rel[..., 0]).max()
    assert seam <= steps + 1e-12, "the seam jumps more than any other pair of neighbours"
    print(f"\n{kind} bark: |r/r0 − 1| up to {np.abs(rel).max() * 100:.2f} % (terms sum {amp.sum() * 100:.2f} %)")


def test_bark_frequencies_fold_below_nyquist():
    for S in (8, 12, 16, 32):
        _, freqs, _, _ = bm.bark_terms("rough", S, seed=2)
        assert freqs.min() >= 2 and freqs.max() <= S // 2 - 1
    assert bm.bark_terms("none", 8)[0].size == 0


# ----------------------------------------------------------------------------- UVs

@pytest.mark.parametrize("curliness", [0.0, 1.0])
def test_v_is_continuous_from_parent_to_child(tree, curliness):
    _, _, _, g = _geometry(tree, curliness=curliness)
    parents_bone = bones.bone_parents(tree.parents)
    child = np.flatnonzero(parents_bone >= 0)
    K, S = g["rings"], 8
    uv = g["uv"].reshape(len(parents_bone), -1, 2)
    # side loops of ring 0 → ring 1, first quad: loops (ring 0, ring 1, ring 1, ring 0)
    v0, v1 = uv[child, 0, 1], uv[child, 1, 1]
    tau = g["tau"][child]
    v_at_head = v0 + (0 - tau[:, 0]) * (v1 - v0) / (tau[:, 1] - tau[:, 0])            # linear in τ
    parent_end = uv[parents_bone[child], 4 * S * (K - 1) - 3, 1]                     # last quad, ring K−1
    np.testing.assert_allclose(parent_end, g["v"][parents_bone[child], -1], atol=1e-12)
    np.testing.assert_allclose(v_at_head, parent_end, atol=1e-9)
    assert (np.diff(g["v"], axis=1) > 0).all()                                        # increasing along
    u = g["uv"][:, 0].reshape(len(parents_bone), -1)[:, :4 * S * (K - 1)].reshape(-1, 4)   # side quads
    assert u.min() >= 0 and u.max() <= 2                                              # each tube from [0, 1)
    np.testing.assert_allclose(np.ptp(u, axis=1), 1.0 / S, atol=1e-12)               # no quad across the seam


def _upper_side(g, b, j):
    """The unit direction from ring ``j`` of bone ``b``'s centre at ``u ≡ U_UP``."""
    S = g["sides"]
    co = g["co"].reshape(len(g["r0"]), g["rings"], S, 3)[b, j] - g["centre"][b, j]
    theta = 2 * np.pi * (bm.U_UP - g["u0"][b, j])          # u = k/S + u0 = θ/2π + u0
    x, z = co[0] / np.linalg.norm(co[0]), co[S // 4] / np.linalg.norm(co[S // 4])   # θ = 0, θ = π/2
    return np.cos(theta) * x + np.sin(theta) * z


@pytest.mark.parametrize("curliness", [0.0, 0.6])
def test_the_upper_side_of_every_ring_is_at_u_up_by_hand(curliness):
    # a vertical trunk, a level limb along +x, a level limb along −y, a limb at 45° and a twig hanging down
    parents = np.array([-1, 0, 1, 1, 1, 1])
    pos = np.array([[0, 0, 0], [0, 0, 2.0], [1.5, 0, 2.0], [0, -1.2, 2.0], [0.7, 0.7, 2.99], [0.2, 0.1, 1.0]])
    rest = bones.rest_frames(parents, pos)
    g = bm.tube_arrays(pos, parents, rest, np.full(5, 0.1), np.full(5, 0.05), 16, curliness=curliness, seed=4)
    up, north = np.array([0, 0, 1.0]), np.array([0, 1.0, 0])
    for b in range(5):
        t = pos[b + 1] - pos[parents[b + 1]]
        t /= np.linalg.norm(t)
        a = up - (t @ up) * t
        want = north - (t @ north) * t if np.linalg.norm(a) < 0.2 else a
        la = np.linalg.norm(a)
        # a level branch's top and a vertical trunk's north exactly; a limb at 45° its top within the
        # north blend; a steep twig's side in its upper half; a curly tube's each within its bend
        bound = 0.9999 if la > 0.999 or la < 1e-9 else 0.97 if la > 0.5 else 0.0
        if curliness:
            bound = min(bound, 0.9)
        for j in range(g["rings"]):
            cos = _upper_side(g, b, j) @ want / np.linalg.norm(want)
            assert cos > bound, (b, j, cos)


def test_bad_mesh_settings_are_input_errors(tree):
    with pytest.raises(InputError, match="curliness"):
        _geometry(tree, curliness=1.5)
    with pytest.raises(InputError, match="bark"):
        _geometry(tree, bark="mossy")
    with pytest.raises(InputError, match="sides"):
        _geometry(tree, sides=2)


# ----------------------------------------------------------------------------- in Blender

def _weights(ob):
    """``(V,)`` group index and weight of every vertex (−1 / 0 when in no group); raises if a
    vertex is in more than one group."""
    me = ob.data
    group = np.full(len(me.vertices), -1)
    weight = np.zeros(len(me.vertices))
    for v in me.vertices:
        gs = v.groups
        assert len(gs) <= 1, f"vertex {v.index} is in {len(gs)} groups"
        if len(gs):
            group[v.index], weight[v.index] = gs[0].group, gs[0].weight
    return group, weight


def test_built_mesh_counts_weights_and_closure(tree):
    res = build.build_tree(bpy.context, tree, "Tree", curliness=0.6, bark="rough")
    ob = res["mesh"]
    B, K, S = len(tree.edges()), bm.CURLY_RINGS, 8
    me = ob.data
    ref = branch_arrays(tree, rig_rest(res["armature"], tree), bm.MeshParams(curliness=0.6, bark="rough"))
    assert len(me.vertices) == K * S * B and len(me.polygons) == len(ref.loop_total)     # joined forks
    group, weight = _weights(ob)
    assert (group >= 0).all() and (weight == 1.0).all()                        # every vertex weighted
    names = [g.name for g in ob.vertex_groups]
    assert names == bones.bone_names(tree.parents)
    np.testing.assert_array_equal(group, np.repeat(np.arange(B), K * S))       # each ring to its bone
    co = assert_closed_tubes(me)
    np.testing.assert_allclose(co.reshape(-1, 3), ref.co, atol=1e-5)
    loop_vert = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", loop_vert)
    np.testing.assert_array_equal(loop_vert, ref.loop_vert)


def test_mesh_settings_come_from_the_tree_meta(tree):
    t = broad_tree(5)
    t.meta["mesh"] = {"curliness": 0.4, "bark": "smooth", "seed": 2}
    p = scene_mesh.mesh_params(t)
    assert (p.curliness, p.bark, p.seed) == (0.4, "smooth", 2)
    p = scene_mesh.mesh_params(t, curliness=0.0, bark="none")
    assert (p.curliness, p.bark) == (0.0, "none")
    res = build.build_tree(bpy.context, t, "T")
    assert len(res["mesh"].data.vertices) == bm.CURLY_RINGS * 8 * len(t.edges())
    with pytest.raises(InputError, match="bark"):
        build.build_tree(bpy.context, t, "U", bark="mossy")
    assert "U" not in bpy.data.collections


def test_timing_and_triangles_of_a_400_bone_tree():
    big = binary_tree(n_bones=400, frames=120)
    rest = bones.rest_frames(big.parents, big.nodes3d[0])
    r_head, r_tail = bm.branch_radii(big.parents, big.radius)
    rows = []
    for kw in ({}, {"curliness": 0.5, "bark": "rough"}, {"curliness": 0.5, "bark": "rough", "sides": 12}):
        sides = kw.get("sides", 8)
        args = {k: v for k, v in kw.items() if k != "sides"}
        t0 = time.perf_counter()
        g = bm.tube_arrays(big.nodes3d[0], big.parents, rest, r_head, r_tail, sides, **args)
        dt = time.perf_counter() - t0
        bpy.ops.wm.read_factory_settings(use_empty=True)
        res = build.build_tree(bpy.context, big, "Big", sides=sides, **args)
        stats = bm.mesh_stats(g)
        assert len(res["mesh"].data.vertices) == stats["vertices"]
        rows.append((kw, stats, dt, res["timings"]["mesh"], res["timings"]["total"]))
        assert res["timings"]["mesh"] < 3.0, "the branch mesh of 400 bones took over 3 s"
    print("\n400 bones x 120 frames:")
    for kw, stats, dt, mesh_t, total in rows:
        print(f"  {kw or 'straight'}: {stats['vertices']} vertices, {stats['triangles']} triangles; "
              f"numpy {dt * 1000:.0f} ms, Blender mesh {mesh_t * 1000:.0f} ms, whole build {total:.2f} s")


@pytest.mark.parametrize("kind", ["none", "smooth", "rough"])
def test_bark_material_is_procedural_and_uv_mapped(kind):
    mat = materials.bark_material("Bark", kind)
    nodes = {n.type for n in mat.node_tree.nodes}
    assert {"TEX_NOISE", "TEX_VORONOI", "BUMP", "BSDF_PRINCIPLED", "OUTPUT_MATERIAL"} <= nodes
    assert ("TEX_WAVE" in nodes) == (kind != "none")                  # furrows along the branch
    links = {(l.from_node.type, l.from_socket.name, l.to_node.type) for l in mat.node_tree.links}
    assert ("TEX_COORD", "UV", "MAPPING") in links                    # follows the mesh's UVs
    bump = next(n for n in mat.node_tree.nodes if n.type == "BUMP")
    assert bump.inputs["Height"].is_linked
    assert bump.inputs["Strength"].default_value == pytest.approx(materials.BARK_LOOK[kind][0])
