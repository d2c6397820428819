"""A forest of variants in Blender (issue 32): each variant built once, its other trees instances
sharing its armature, meshes and action, played from their own frame of the loop by an NLA strip;
their pose equals the variant's at the shifted frame, an instance exports as its variant's
motion, and removing the forest leaves nothing behind."""
import os

import bpy
import numpy as np
import pytest
from test_exports import read_glb

from trees import empty_scene, registered  # noqa: F401  (autouse fixtures)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]


def _forest(n: int = 6, variants: int = 2, frames: int = 41):
    p = bpy.context.scene.tree_video
    p.gen_frames, p.gen_nodes, p.gen_seed = frames, 80, 3
    p.envelope_source, p.gen_height = "CIRCLE", 5.0
    p.forest_count, p.forest_variants, p.forest_spacing = n, variants, 7.0
    assert bpy.ops.tree_video.generate_forest() == {"FINISHED"}
    trees = sorted(bpy.data.collections["Forest"].children, key=lambda c: c.name)
    return [next(o for o in c.objects if o.type == "ARMATURE") for c in trees], trees


def _quats(rig) -> np.ndarray:
    return np.array([pb.rotation_quaternion for pb in rig.pose.bones])


def test_instances_share_the_variants_data_and_play_them_out_of_step():
    from tree_from_video.operators.scene.instances import INSTANCE_KEY
    rigs, colls = _forest()
    own = [r for r, c in zip(rigs, colls) if not c.get(INSTANCE_KEY)]
    inst = [(r, c) for r, c in zip(rigs, colls) if c.get(INSTANCE_KEY)]
    assert len(own) == 2 and len(inst) == 4
    assert len({r.data.name for r in rigs}) == 2                      # two armatures for six trees
    meshes = [o for c in colls for o in c.objects if o.type == "MESH"]
    assert len(meshes) == 12 and len({o.data.name for o in meshes}) == 4
    assert len(bpy.data.actions) == 2 + 2                             # two sways, two leaf flaps
    offsets = []
    scene = bpy.context.scene
    for rig, coll in inst:
        variant = bpy.data.collections[coll[INSTANCE_KEY]]
        vrig = next(o for o in variant.objects if o.type == "ARMATURE")
        assert rig.data == vrig.data and rig.animation_data.action is None
        for ob in coll.objects:                                       # parented and skinned to their own rig
            if ob.type == "MESH":
                assert ob.parent == rig
                assert all(m.object == rig for m in ob.modifiers if m.type == "ARMATURE")
        strip = rig.animation_data.nla_tracks[0].strips[0]
        L = int(round(strip.action_frame_end - strip.action_frame_start))
        assert L == 40 and strip.action == vrig.animation_data.action
        o = int(round(1 - strip.frame_start))
        offsets.append(o)
        worst = 0.0
        for f in (1, 9, 23, 40, 41):
            scene.frame_set(f)
            q = _quats(rig)
            scene.frame_set(1 + (f - 1 + o) % L)
            worst = max(worst, float(np.abs(q - _quats(vrig)).max()))     # the channels' values
        print(f"\n{coll.name}: offset {o} frames of {L}, pose against its variant's shifted frame: {worst:.2e}")
        assert worst < 1e-6
        s = rig.scale[0]
        assert rig.scale[0] == rig.scale[1] == rig.scale[2] and 0.8 < s < 1.25
    assert len(set(offsets)) >= 3 and any(offsets)


def test_an_instance_exports_as_its_variant_and_is_put_back(tmp_path):
    from tree_from_video.operators.scene import export
    from tree_from_video.operators.scene.instances import INSTANCE_KEY
    from tree_from_video.operators.scene.trees import tree_objects
    rigs, colls = _forest(n=3, variants=1, frames=25)
    rig, coll = next((r, c) for r, c in zip(rigs, colls) if c.get(INSTANCE_KEY))
    variant_action = bpy.data.collections[coll[INSTANCE_KEY]].objects[0].animation_data
    name = next(o for o in bpy.data.collections[coll[INSTANCE_KEY]].objects if o.type == "ARMATURE") \
        .animation_data.action.name
    path = export.export_gltf(str(tmp_path / "instance.glb"), tree_objects(coll))
    doc, _ = read_glb(path)
    assert [a["name"] for a in doc["animations"]] == [name]
    times = {doc["accessors"][s["input"]]["count"] for a in doc["animations"] for s in a["samplers"]}
    assert times == {25}                                              # the loop's 24 frames and its closing one
    assert rig.animation_data.action is None and rig.animation_data.use_nla     # put back
    assert rig.animation_data.nla_tracks[0].strips[0].action.name == name
    assert variant_action is not None and os.path.getsize(path) > 0


def test_removing_the_forest_leaves_no_data():
    from tree_from_video.operators.scene.objects import remove_collection
    _forest(n=4, variants=2, frames=17)
    remove_collection(bpy.data.collections["Forest"])
    left = [len(getattr(bpy.data, k)) for k in ("objects", "meshes", "armatures", "actions", "collections")]
    assert left == [0, 0, 0, 0, 0]
