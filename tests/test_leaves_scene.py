"""Leaf clusters in Blender: one bone per cluster keyed with its flutter, one skinned leaf mesh;
the clusters ride their branches exactly, a failed build leaves nothing, and the leaves reach
FBX, glTF and USD animated (read back from the files)."""
import os

import bpy
import numpy as np
import pytest

from tree_from_video.core import pipeline
from tree_from_video.core.detail import leaf_clusters
from tree_from_video.operators.scene import action_api, build, export, leaves, materials

from samples import plain_settings
from trees import (
    ROOT,
    empty_scene,  # noqa: F401  (autouse fixture)
    tree_height,
)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

FRAMES = 60


@pytest.fixture(scope="module")
def tree():
    folder = os.path.join(ROOT, "sample_videos", "broad")
    s = plain_settings(frames=f"0:{FRAMES}")
    s.leaves.max_clusters = 150                    # keeps the export tests quick; placement is the same
    res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
    t = pipeline.build_3d(res, s, name="Leafy")
    assert t.leaves is not None and t.leaves.count == 150
    return t


def _leaf_names(tree):
    return leaves.leaf_bone_names(tree.leaves.count)


def _rotation_angle_about(q, axis):
    """Signed angles ``(F,)`` of quaternions ``(F, 4)`` (w, x, y, z, w ≥ 0: the exporter may write
    either of q and −q) about ``axis``."""
    return 2 * np.arctan2(q[:, 1:] @ axis, q[:, 0])


def test_leaf_bones_ride_their_branches_and_flutter(tree):
    built = build.build_tree(bpy.context, tree, "Leafy")
    rig, leaf_obj = built["armature"], built["leaves"]
    names = _leaf_names(tree)
    L = tree.leaves
    assert built["leaf_polygons"] == len(leaf_obj.data.polygons) == L.count * L.cards
    assert len(rig.data.bones) == tree.n_nodes - 1 + L.count
    for n, node in zip(names[:20], L.node[:20]):
        assert rig.data.bones[n].parent.name == f"B{node:03d}"
    # every leaf vertex in exactly one group (its cluster's bone), weight 1
    groups = {g.index: g.name for g in leaf_obj.vertex_groups}
    per = 4 * L.cards
    for v in list(leaf_obj.data.vertices)[:: per // 2]:
        assert len(v.groups) == 1 and v.groups[0].weight == 1.0
        assert groups[v.groups[0].group] == names[v.index // per]
    # the flutter Blender plays: one period of the steady sine under a Cycles modifier (core/keys.py)
    cycle = built["keys"].cycle
    played = cycle.played
    curves = [fc for fc in action_api.action_fcurves(built["action"]) if fc.data_path.startswith('pose.bones["L')]
    assert len(curves) == 2 * L.count
    assert {len(fc.keyframe_points) for fc in curves} == {len(cycle.frames)}
    assert {tuple(m.type for m in fc.modifiers) for fc in curves} == {("CYCLES",)}
    centres = leaf_clusters.leaf_centres(tree)
    tol = 1e-3 * tree_height(tree)
    mw = np.array(rig.matrix_world)
    for frame in (1, 25, FRAMES):
        bpy.context.scene.frame_set(frame)
        heads = np.array([rig.pose.bones[n].head for n in names]) @ mw[:3, :3].T + mw[:3, 3]
        err = np.abs(heads - centres[frame - 1]).max()
        assert err <= tol, (frame, err)
        q = np.array([rig.pose.bones[n].rotation_quaternion for n in names])
        np.testing.assert_allclose(_rotation_angle_about(q, np.array([0.0, 1.0, 0.0])), played[frame - 1],
                                   atol=1e-4)
    # every leaf's own flap: four shape keys whose keyed weights rebuild sin(ωt + φ_leaf)
    keys = leaf_obj.data.shape_keys
    assert [k.name for k in keys.key_blocks] == ["Basis", *leaves.FLAP_KEYS]
    want = leaf_clusters.flap_weights(tree.n_frames, tree.fps, L.leaf_hz)
    for i, name in enumerate(leaves.FLAP_KEYS):
        path = f'key_blocks["{name}"].value'
        fc = next(f for f in action_api.action_fcurves(keys.animation_data.action) if f.data_path == path)
        got = np.array([fc.evaluate(f) for f in range(1, tree.n_frames + 1)])
        np.testing.assert_allclose(got, want[:, i], atol=1e-5)
    # with the bones switched off, a leaf tip moves by Δ sin(ωt + φ) about its stem
    leaf_obj.modifiers["Armature"].show_viewport = False
    C, S, phase = leaf_clusters.leaf_flap_offsets(leaf_clusters.leaf_mesh(L)["co"], L.leaf_angle, L.seed)
    tip = 2                                        # card 0's first tip vertex
    rest = np.array(keys.key_blocks["Basis"].data[tip].co)
    t = np.arange(tree.n_frames) / tree.fps
    for frame in (3, 7, 11):
        bpy.context.scene.frame_set(frame)
        ev = leaf_obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        moved = np.array(ev.data.vertices[tip].co) - rest
        delta = C[tip] / np.cos(phase[0]) if abs(np.cos(phase[0])) > 0.3 else S[tip] / np.sin(phase[0])
        np.testing.assert_allclose(moved, delta * np.sin(2 * np.pi * L.leaf_hz * t[frame - 1] + phase[0]), atol=1e-5)
    leaf_obj.modifiers["Armature"].show_viewport = True
    print(f"\n{L.count} leaf bones + {tree.n_nodes - 1} branch bones, {built['leaf_polygons']} leaf polygons, "
          f"build {built['timings']['total']:.2f} s (leaves {built['timings']['leaves']:.2f} s)")


def test_a_failed_leaf_build_leaves_nothing(tree, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("leaf mesh failed")
    monkeypatch.setattr(leaves, "build_leaf_mesh", broken)
    with pytest.raises(RuntimeError, match="leaf mesh failed"):
        build.build_tree(bpy.context, tree, "Leafy")
    for coll in ("objects", "meshes", "armatures", "materials", "images", "actions"):
        assert len(getattr(bpy.data, coll)) == 0, coll
    assert "Leafy" not in bpy.data.collections


def _glb_flutter(doc, binary, node):
    from test_exports import accessor
    anim = doc["animations"][0]
    for c in anim["channels"]:
        if c["target"]["node"] == node and c["target"]["path"] == "rotation":
            q = accessor(doc, binary, anim["samplers"][c["sampler"]]["output"])
            return q[:, [3, 0, 1, 2]]                        # glTF xyzw → wxyz
    return None


def test_leaves_are_in_the_gltf_fbx_and_usd_exports_animated(tree, tmp_path):
    from test_exports import accessor, read_glb
    built = build.build_tree(bpy.context, tree, "Leafy")
    objects = [built["armature"], built["mesh"], built["leaves"]]
    names = _leaf_names(tree)
    L = tree.leaves
    played = built["keys"].cycle.played              # the flutter Blender plays (and exports)

    # glTF: the leaf bones are joints of the skin, each rotation channel turns about one axis
    # by the flutter angle (up to its constant rest offset)
    glb = tmp_path / "tree.glb"
    export.export_gltf(glb, objects)
    doc, binary = read_glb(glb)
    joints = {doc["nodes"][j]["name"]: j for j in doc["skins"][0]["joints"]}
    assert set(names) <= set(joints)
    # no empty node (issue 32 saw an empty "Leaves" one): each is a joint, a mesh or a parent
    empty = [n.get("name") for i, n in enumerate(doc["nodes"])
             if i not in joints.values() and "mesh" not in n and not n.get("children")]
    assert empty == []
    worst = 0.0
    for k in range(0, L.count, 15):
        q = _glb_flutter(doc, binary, joints[names[k]])
        assert q is not None and len(q) == FRAMES
        rel = np.array([_qmul(_qconj(q[0]), qt) for qt in q])          # rotation since frame 1
        rel *= np.where(rel[:, :1] < 0, -1.0, 1.0)                     # q and -q: the same rotation
        axis = np.linalg.svd(rel[:, 1:], full_matrices=False)[2][0]
        angle = _rotation_angle_about(rel, axis)
        want = played[:, k] - played[0, k]
        err = min(np.abs(angle - want).max(), np.abs(angle + want).max())   # the axis sign is free
        worst = max(worst, err)
    print(f"\nglTF: {len(names)} leaf joints; flutter angle error ≤ {np.degrees(worst):.4f}°")
    assert worst <= 1e-3
    leaves_mesh = next(m for m in doc["meshes"] if "Leaves" in m["name"])
    assert len(leaves_mesh["primitives"][0]["targets"]) == 4                  # the per-leaf flap
    leaves_node = next(i for i, n in enumerate(doc["nodes"]) if n.get("mesh") == doc["meshes"].index(leaves_mesh))
    anim = doc["animations"][0]
    weights = [c for c in anim["channels"] if c["target"]["path"] == "weights" and c["target"]["node"] == leaves_node]
    assert len(weights) == 1
    w = accessor(doc, binary, anim["samplers"][weights[0]["sampler"]]["output"]).reshape(FRAMES, 4)
    np.testing.assert_allclose(w, leaf_clusters.flap_weights(FRAMES, tree.fps, L.leaf_hz), atol=1e-4)

    # FBX: re-import keeps the leaf bones and the leaf mesh's groups
    fbx = tmp_path / "tree.fbx"
    export.export_fbx(fbx, objects)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.fbx(filepath=str(fbx))
    rig = next(ob for ob in bpy.context.scene.objects if ob.type == "ARMATURE")
    assert set(names) <= {b.name for b in rig.data.bones}
    leaf_mesh = next(ob for ob in bpy.context.scene.objects if ob.type == "MESH" and "Leaves" in ob.name)
    assert len(leaf_mesh.data.polygons) == L.count * L.cards
    assert set(names) <= {g.name for g in leaf_mesh.vertex_groups}
    keys = leaf_mesh.data.shape_keys
    assert keys is not None and len(keys.key_blocks) == 5 and keys.animation_data.action is not None

    # USD (where Blender has it): the leaf bones are joints of the skeleton, animated
    if not export.has_usd():
        print("USD: this Blender has no USD exporter (the clear error is tested in test_exports)")
        return
    bpy.ops.wm.read_factory_settings(use_empty=True)
    built = build.build_tree(bpy.context, tree, "Leafy")
    usd = tmp_path / "tree.usda"
    export.export_usd(usd, [built["armature"], built["mesh"], built["leaves"]])
    try:
        from pxr import Usd, UsdSkel
    except ImportError:
        text = usd.read_text()
        assert all(n in text for n in names[:10])
        return
    stage = Usd.Stage.Open(str(usd))
    skel = next(UsdSkel.Skeleton(p) for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton))
    anim = next(UsdSkel.Animation(p) for p in stage.Traverse() if p.IsA(UsdSkel.Animation))
    joints = [str(j).rsplit("/", 1)[-1] for j in skel.GetJointsAttr().Get()]
    assert set(names) <= set(joints)
    assert len(anim.GetRotationsAttr().GetTimeSamples()) == FRAMES
    assert len(anim.GetBlendShapesAttr().Get()) == 4                          # the per-leaf flap
    assert len(anim.GetBlendShapeWeightsAttr().GetTimeSamples()) == FRAMES


def _qconj(q):
    return np.array([q[0], -q[1], -q[2], -q[3]])


def _qmul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def test_a_users_leaf_image_is_packed_and_a_bad_one_is_refused(tree, tmp_path):
    import cv2

    from tree_from_video.core.errors import InputError
    img = np.zeros((32, 16, 4), np.uint8)
    img[4:28, 4:12] = (40, 160, 60, 255)                  # BGRA: a green blade
    good = tmp_path / "leaf.png"
    cv2.imwrite(str(good), img)
    built = build.build_tree(bpy.context, tree, "Leafy", leaf_image=str(good))
    mat = built["leaves"].data.materials[0]
    images = materials.material_images(mat)
    assert len(images) == 1 and tuple(images[0].size) == (16, 32) and images[0].packed_file is not None
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bad = tmp_path / "leaf.png.txt"
    bad.write_text("not an image")
    with pytest.raises(InputError, match="leaf image|not an image"):
        build.build_tree(bpy.context, tree, "Leafy", leaf_image=str(bad))
    for coll in ("objects", "meshes", "armatures", "materials", "images", "actions"):
        assert len(getattr(bpy.data, coll)) == 0, coll
