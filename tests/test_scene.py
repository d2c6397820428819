"""The animated tree in Blender: bone maths by hand, the built armature/keys/mesh, the evaluated pose
against the input positions, and all-or-nothing building (bpy wheel and real Blender)."""
import math

import bpy
import numpy as np
import pytest

from tree_from_video.core import bones, keys, rotations
from tree_from_video.core.detail.branch_mesh import branch_radii
from tree_from_video.core.errors import InputError
from tree_from_video.core.tree3d import Tree3D
from tree_from_video.operators.scene import action_api, armature, branch_mesh, build, objects

from trees import (
    assert_closed_tubes,
    binary_tree,
    broad_tree,
    empty_scene,  # noqa: F401  (autouse fixture)
    expected,
    pose_tails,
    tree_height,
)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

S2 = math.sqrt(0.5)


@pytest.fixture(scope="module")
def tree():
    return broad_tree(60)


def _ids():
    return {attr: set(getattr(bpy.data, attr).keys())
            for attr in ("objects", "meshes", "armatures", "actions", "materials", "collections")}


# ----------------------------------------------------------------------------- bones.py by hand

def _chain(frames):
    """3 nodes 0-1-2 (two bones), positions per frame."""
    return np.array([-1, 0, 1]), np.array(frames, np.float64)


def test_two_bone_chain_bent_90_degrees_by_hand():
    # frame 0: straight up; frame 1: the upper bone bends to +x; frame 2: the whole chain lies along +x
    parents, nodes = _chain([[[0, 0, 0], [0, 0, 1], [0, 0, 2]],
                             [[0, 0, 0], [0, 0, 1], [1, 0, 1]],
                             [[0, 0, 0], [1, 0, 0], [2, 0, 0]]])
    assert bones.bone_names(parents) == ["B001", "B002"]
    assert bones.bone_parents(parents).tolist() == [-1, 0]
    # Blender's roll-0 rest matrix of a bone pointing +z: X = +x, Y = +z, Z = -y
    up = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    rest = np.stack([up, up])
    np.testing.assert_allclose(bones.rest_frames(parents, nodes[0]), rest, atol=1e-12)

    world = bones.world_rotations(parents, nodes)
    np.testing.assert_allclose(world[0], [[1, 0, 0, 0], [1, 0, 0, 0]], atol=1e-12)
    # frame 1: +z → +x is +90° about world +y
    np.testing.assert_allclose(world[1], [[1, 0, 0, 0], [S2, 0, S2, 0]], atol=1e-12)

    local = bones.local_rotations(parents, nodes, rest)
    assert local.shape == (3, 2, 4)
    np.testing.assert_allclose(local[0], [[1, 0, 0, 0], [1, 0, 0, 0]], atol=1e-12)
    # world +y is the bone's -Z: +90° about -Z in bone space
    np.testing.assert_allclose(local[1], [[1, 0, 0, 0], [S2, 0, 0, -S2]], atol=1e-12)
    # frame 2: the lower bone turns, the upper one inherits it and stays straight relative to it
    np.testing.assert_allclose(local[2], [[S2, 0, 0, -S2], [1, 0, 0, 0]], atol=1e-12)

    np.testing.assert_allclose(bones.pose_tails(parents, nodes[0], rest, local), nodes, atol=1e-12)


def test_local_rotations_reproduce_positions_through_forward_kinematics():
    tree = binary_tree(n_bones=31, frames=40, seed=3)
    rest = bones.rest_frames(tree.parents, tree.nodes3d[0])
    local = bones.local_rotations(tree.parents, tree.nodes3d, rest)
    assert local.shape == (40, 31, 4)
    np.testing.assert_allclose(np.linalg.norm(local, axis=-1), 1.0, atol=1e-12)
    fk = bones.pose_tails(tree.parents, tree.nodes3d[0], rest, local)
    assert np.abs(fk - tree.nodes3d).max() < 1e-5 * tree_height(tree)       # float32 input


def test_quaternions_are_sign_continuous_and_swings_untwisted():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(30, 5, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    q = np.cumsum(q * 0.1, axis=0)                          # a smooth path ...
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    flipped = q * rng.choice([-1.0, 1.0], size=(30, 5, 1))  # ... with random sign flips
    c = rotations.make_continuous(flipped)
    assert (np.sum(c[1:] * c[:-1], axis=-1) >= 0).all()
    np.testing.assert_allclose(np.abs(np.sum(c * q, axis=-1)), 1.0, atol=1e-12)   # same rotations
    # the swing has no twist: its axis is perpendicular to both directions
    s = rotations.swing(np.array([0.0, 0, 1]), np.array([[1.0, 0, 0], [0, 0, -1]]))
    np.testing.assert_allclose(s[0], [S2, 0, S2, 0], atol=1e-12)
    assert abs(s[1, 0]) < 1e-12 and abs(s[1, 3]) < 1e-12                 # 180° about an axis ⟂ z


def test_matrix_quaternion_round_trip():
    rng = np.random.default_rng(1)
    q = rng.normal(size=(500, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1
    np.testing.assert_allclose(rotations.matrix_to_quat(rotations.quat_to_matrix(q)), q, atol=1e-9)


def test_degenerate_trees_are_input_errors():
    with pytest.raises(InputError, match="zero length"):
        bones.local_rotations(np.array([-1, 0]), np.zeros((2, 2, 3)), np.stack([np.eye(3)]))
    nodes = np.zeros((2, 2, 3))
    nodes[:, 1, 2] = 1
    nodes[1, 1, 0] = np.nan
    with pytest.raises(InputError, match="non-finite"):
        bones.world_rotations(np.array([-1, 0]), nodes)


# ----------------------------------------------------------------------------- the built scene

def test_build_bones_keys_and_scene_timing(tree):
    res = build.build_tree(bpy.context, tree, "Tree", every_key=True)
    rig, coll = res["armature"], res["collection"]
    assert coll.name == "Tree" and coll.name in bpy.context.scene.collection.children
    assert {ob.name for ob in coll.objects} == {"Tree Rig", "Tree Branches"}
    edges = tree.edges()
    names = [f"B{c:03d}" for c in edges[:, 1]]
    bones = rig.data.bones
    assert len(bones) == len(edges) == tree.n_nodes - 1
    bone_of_node = {int(c): f"B{c:03d}" for c in edges[:, 1]}
    for (p, _), name in zip(edges, names):
        b = bones[name]
        want_parent = bone_of_node.get(int(p))
        assert (b.parent.name if b.parent else None) == want_parent
        assert b.use_connect == (want_parent is not None)
    assert all(pb.rotation_mode == "QUATERNION" for pb in rig.pose.bones)

    F, B = tree.n_frames, len(edges)
    fcurves = list(action_api.action_fcurves(res["action"]))
    assert len(fcurves) == 4 * B
    assert sum(len(fc.keyframe_points) for fc in fcurves) == F * B * 4
    paths = {(fc.data_path, fc.array_index) for fc in fcurves}
    assert paths == {(f'pose.bones["{n}"].rotation_quaternion', i) for n in names for i in range(4)}
    fc = fcurves[7]
    co = np.empty(2 * F, np.float32)
    fc.keyframe_points.foreach_get("co", co)
    np.testing.assert_array_equal(co[0::2], np.arange(1, F + 1))
    assert {k.interpolation for k in fc.keyframe_points} == {"LINEAR"}
    assert rig.animation_data.action == res["action"]

    scene = bpy.context.scene
    assert (scene.frame_start, scene.frame_end) == (1, F)
    assert scene.render.fps == 24 and scene.render.fps_base == 1.0
    print(f"\nbuild 234 bones x 60 frames: {res['timings']}")


def test_fractional_fps_uses_fps_base(tree):
    t = Tree3D(tree.parents, tree.nodes3d[:10], tree.radius, tree.level, 29.97)
    build.build_tree(bpy.context, t, "Tree", mesh=False)
    r = bpy.context.scene.render
    assert r.fps == 30
    assert r.fps / r.fps_base == pytest.approx(29.97, rel=1e-6)
    assert bpy.context.scene.frame_end == 10


def test_evaluated_pose_matches_input_positions(tree):
    res = build.build_tree(bpy.context, tree, "Tree", every_key=True)
    names = [f"B{c:03d}" for c in tree.edges()[:, 1]]
    tol = 1e-4 * tree_height(tree)
    worst = 0.0
    for k in (1, 2, 17, 31, 44, 60):
        bpy.context.scene.frame_set(k)
        err = np.abs(pose_tails(res["armature"], names) - expected(tree, k)[1]).max()
        worst = max(worst, err)
        assert err <= tol, f"frame {k}: tail error {err:.2e} m > {tol:.2e} m"
    print(f"\nworst tail error {worst:.2e} m (tolerance {tol:.2e} m)")


def _segment_distance(p, a, b):
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.sum(ab * ab, axis=-1), 0, 1)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def test_evaluated_mesh_follows_the_bones(tree):
    res = build.build_tree(bpy.context, tree, "Tree", every_key=True)
    ob = res["mesh"]
    sides = 8
    B = len(tree.edges())
    assert len(ob.data.vertices) == 2 * sides * B
    assert [g.name for g in ob.vertex_groups] == [f"B{c:03d}" for c in tree.edges()[:, 1]]
    assert ob.parent == res["armature"] and ob.modifiers[0].type == "ARMATURE"
    assert ob.modifiers[0].object == res["armature"]
    assert ob.data.materials[0] == res["material"] and res["material"].node_tree is not None
    v = ob.data.vertices[2 * sides * 5 + 3]
    assert [(ob.vertex_groups[g.group].name, g.weight) for g in v.groups] == [(f"B{tree.edges()[5, 1]:03d}", 1.0)]
    r_head, r_tail = branch_radii(tree.parents, tree.radius)
    reach = 1.5 * np.maximum(r_head, r_tail) + 1e-4                 # ring radius, head overlap
    vert_bone = np.repeat(np.arange(B), 2 * sides)
    positions = {}
    for k in (1, 30, 60):
        bpy.context.scene.frame_set(k)
        co, _ = objects.evaluated_world_mesh(ob)
        heads, tails, _ = expected(tree, k)
        d = _segment_distance(co, heads[vert_bone], tails[vert_bone])
        assert (d <= reach[vert_bone]).all(), f"frame {k}: a vertex is {d.max():.3f} m from its bone"
        positions[k] = co
    moved = np.linalg.norm(positions[30] - positions[1], axis=1).max()
    assert moved > 0.05, f"the evaluated mesh did not move ({moved} m)"


def test_mesh_is_closed_with_outward_normals(tree):
    me = build.build_tree(bpy.context, tree, "Tree")["mesh"].data
    assert_closed_tubes(me)
    uv = np.empty(len(me.loops) * 2, np.float32)
    me.uv_layers["UVMap"].data.foreach_get("uv", uv)
    # u goes round a tube once from its u0 in [0, 1) (the tube's upper side at u ≡ 0.5); a joined
    # fork's face takes its vertices' u to within half a turn of its first (the bark tile repeats):
    # no face spans a whole turn
    u = uv[0::2]
    start = np.empty(len(me.polygons), np.int64)
    me.polygons.foreach_get("loop_start", start)
    face = np.repeat(np.arange(len(start)), np.diff(np.append(start, len(u))))
    span = np.zeros(len(start))
    np.maximum.at(span, face, np.abs(u - u[start][face]))
    assert np.isfinite(uv).all() and -0.5 <= u.min() and u.max() < 2.5 and span.max() <= 0.5 + 1e-6


# ----------------------------------------------------------------------------- all or nothing

def _raise_after(original):
    def wrapper(*args, **kwargs):
        original(*args, **kwargs)
        raise RuntimeError("injected failure")
    return wrapper


@pytest.mark.parametrize("where", ["edit_mode", "keys", "mesh"])
def test_failure_mid_build_leaves_nothing(tree, monkeypatch, where):
    before = _ids()
    scene = bpy.context.scene
    scene.render.fps, scene.frame_end = 50, 77
    if where == "edit_mode":
        monkeypatch.setattr(armature, "_edit_bones", _raise_after(armature._edit_bones))
    elif where == "keys":
        calls = {"n": 0}
        original = action_api.write_keys

        def flaky(*args):
            calls["n"] += 1
            if calls["n"] == 300:
                raise RuntimeError("injected failure")
            original(*args)
        monkeypatch.setattr(action_api, "write_keys", flaky)
    else:
        monkeypatch.setattr(branch_mesh, "build_mesh", _raise_after(branch_mesh.build_mesh))
    with pytest.raises(RuntimeError, match="injected failure"):
        build.build_tree(bpy.context, tree, "Tree")
    assert _ids() == before
    assert bpy.context.mode == "OBJECT"
    assert (scene.render.fps, scene.frame_start, scene.frame_end) == (50, 1, 77)   # scene settings kept


def test_existing_collection_is_replaced_only_when_asked(tree, monkeypatch):
    first = build.build_tree(bpy.context, tree, "Tree")
    assert first["armature"].animation_data.action.frame_range[1] == 60
    after_first = _ids()
    with pytest.raises(InputError, match="'Tree' already exists"):
        build.build_tree(bpy.context, tree, "Tree")
    assert _ids() == after_first

    short = Tree3D(tree.parents, tree.nodes3d[:30], tree.radius, tree.level, tree.fps)
    # a replacement that fails at the last step leaves the old tree as it was
    def boom(collection):
        raise RuntimeError("boom")
    monkeypatch.setattr(objects, "remove_collection", boom)
    with pytest.raises(RuntimeError, match="boom"):
        build.build_tree(bpy.context, short, "Tree", replace=True)
    assert _ids() == after_first
    monkeypatch.undo()

    res = build.build_tree(bpy.context, short, "Tree", replace=True)
    assert _ids() == after_first                      # same names: old data gone, new data renamed
    assert res["armature"].name == "Tree Rig" and res["mesh"].name == "Tree Branches"
    assert res["armature"].animation_data.action.frame_range[1] == 30
    assert len(bpy.data.collections["Tree"].objects) == 2


def test_bad_inputs_are_refused_before_building(tree):
    before = _ids()
    with pytest.raises(InputError, match="frame rate"):
        build.build_tree(bpy.context, Tree3D(tree.parents, tree.nodes3d, tree.radius, tree.level, 0.0), "T")
    with pytest.raises(InputError, match="sides"):
        build.build_tree(bpy.context, tree, "T", sides=2)
    with pytest.raises(InputError, match="collection name"):
        build.build_tree(bpy.context, tree, "")
    assert _ids() == before


# ----------------------------------------------------------------------------- timing

def test_timing_127_bones_300_frames_and_full_sample():
    small = binary_tree(n_bones=127, frames=300)
    res = build.build_tree(bpy.context, small, "Binary", every_key=True)    # the writer's speed per key
    t = res["timings"]
    print(f"\n127 bones x 300 frames: rig arrays {t['rig arrays']:.3f} s, keys {t['keys']:.3f} s, "
          f"armature {t['armature']:.3f} s, mesh {t['mesh']:.3f} s, total {t['total']:.3f} s")
    fcurves = list(action_api.action_fcurves(res["action"]))
    assert sum(len(fc.keyframe_points) for fc in fcurves) == 127 * 300 * 4
    # target 0.2 s; the bound leaves room for a loaded 2-core machine but not for per-key Python
    assert t["rig arrays"] + t["keys"] < 0.8
    full = broad_tree(None)
    res = build.build_tree(bpy.context, full, "Broad")
    t = res["timings"]
    print(f"broad sample 234 bones x 180 frames: rig arrays {t['rig arrays']:.3f} s, keys {t['keys']:.3f} s, "
          f"armature {t['armature']:.3f} s, mesh {t['mesh']:.3f} s, total {t['total']:.3f} s")


def test_solver_output_builds_and_poses_exactly():
    """The reconstruction itself (video → skeleton → lift → probabilistic motion, 30 frames of the
    committed sample) built as an armature: one bone per skeleton edge, its curves baked samples or
    reduced Bezier keys, and the evaluated pose at every frame within the keys' tolerance
    (core/keys.py KEY_TOLERANCE of the height) of the solver's nodes."""
    import os

    from tree_from_video.core import pipeline

    from samples import plain_settings
    from trees import ROOT
    folder = os.path.join(ROOT, "sample_videos", "broad")
    res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"),
                       plain_settings(frames="0:30"))
    tree = pipeline.build_3d(res, plain_settings(frames="0:30"), name="Solved")
    built = build.build_tree(bpy.context, tree, "Solved", leaves=False)   # leaves: test_leaves_scene
    rig = built["armature"]
    names = bones.bone_names(tree.parents)
    assert len(rig.data.bones) == len(res.skeleton.edges()) == tree.n_nodes - 1
    curves = list(action_api.action_fcurves(built["action"]))
    assert len(curves) == 4 * len(names)
    # each bone's curves: baked samples on every frame, or fewer Bezier keys (issue 32)
    kept = built["keys"]
    for fc in curves:
        n_keys, n_samples = len(fc.keyframe_points), len(fc.sampled_points)
        assert (n_keys, n_samples) in {(0, tree.n_frames)} or (n_samples == 0 and 2 <= n_keys < tree.n_frames)
    assert sum(len(fc.keyframe_points) for fc in curves) == 4 * kept.bones[:, ~kept.bones.all(0)].sum()
    # the evaluated pose at every frame: within the keys' stated tolerance of the solver's nodes
    tol = keys.KEY_TOLERANCE * tree_height(tree) + 1e-4 * tree_height(tree)
    worst = _worst_tail_error(rig, names, tree)
    print(f"\nsolved 30 frames: {kept.bones.all(0).sum()} of {len(names)} bones sampled, "
          f"largest tail error {worst / tree_height(tree):.4%} of H (tolerance {keys.KEY_TOLERANCE:.2%})")
    assert worst <= tol


def test_smooth_motion_plays_from_few_bezier_keys(tree):
    """The broad sample's true motion (smooth: no tracking jitter) keeps a fraction of its keys as
    Bezier keys whose FREE handles make Blender play the cubic core/keys.py checked: the evaluated
    pose at every frame within the stated tolerance of the motion (issue 32)."""
    res = build.build_tree(bpy.context, tree, "Tree", mesh=False)
    rig, kept = res["armature"], res["keys"]
    names = bones.bone_names(tree.parents)
    curves = list(action_api.action_fcurves(res["action"]))
    n_keys = sum(len(fc.keyframe_points) for fc in curves)
    assert n_keys < 0.5 * 4 * len(names) * tree.n_frames
    bez = next(fc for fc in curves if 2 < len(fc.keyframe_points) < tree.n_frames)
    assert {k.interpolation for k in bez.keyframe_points} == {"BEZIER"}
    assert {k.handle_left_type for k in bez.keyframe_points} == {"FREE"}
    H = tree_height(tree)
    worst = _worst_tail_error(rig, names, tree)
    print(f"\nbroad truth {tree.n_frames} frames: {n_keys} keys for {4 * len(names) * tree.n_frames} "
          f"frames x channels, largest tail error {worst / H:.4%} of H")
    assert worst <= keys.KEY_TOLERANCE * H * 1.01 and kept.error <= keys.KEY_TOLERANCE * H


def _worst_tail_error(rig, names, tree) -> float:
    """The largest distance (m) of the rig's evaluated bone tails from the tree's nodes over every frame."""
    worst = 0.0
    for frame in range(1, tree.n_frames + 1):
        bpy.context.scene.frame_set(frame)
        _, tails, _ = expected(tree, frame)
        worst = max(worst, float(np.abs(pose_tails(rig, names) - tails).max()))
    return worst
