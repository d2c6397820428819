"""How a new tree looks in the viewport: no bone sticks drawn (all bones in hidden bone
collections, still exported), nothing selected (no orange outline), and Solid view colours that
are the leaves' and the bark's own (Viewport Display colour), not grey."""
import bpy
import numpy as np
import pytest

from tree_from_video.core import bones
from tree_from_video.core.detail.albedo import srgb_to_linear
from tree_from_video.core.detail.grown_leaves import grow_leaves
from tree_from_video.operators.scene import build

from trees import (
    broad_tree,
    empty_scene,  # noqa: F401  (autouse fixture)
)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

#: a clear leaf green (sRGB) for the grown leaves: the solid view must show it, not a grey
GREEN = (0.25, 0.55, 0.15)


@pytest.fixture(scope="module")
def leafy():
    tree = broad_tree(24)
    tree.leaves = grow_leaves(tree, {"colour": GREEN, "radius_frac": 0.04, "cards": 6, "per_node": 0.5}, seed=3)
    assert tree.leaves is not None and tree.leaves.count > 20
    return tree


def test_new_tree_draws_no_bones_lands_unselected_and_has_solid_view_colours(leafy):
    cube = bpy.data.objects.new("User Cube", bpy.data.meshes.new("User Cube"))
    bpy.context.scene.collection.objects.link(cube)
    cube.select_set(True)
    bpy.context.view_layer.objects.active = cube

    built = build.build_tree(bpy.context, leafy, "Look")
    rig = built["armature"]
    new = list(built["collection"].all_objects)
    assert len(new) == 3                                           # rig, branches, leaves
    assert [ob.name for ob in new if ob.select_get()] == []        # no orange outline over the tree
    assert bpy.context.view_layer.objects.active == rig            # the rig's properties show

    # every bone (branches and leaf clusters) sits only in hidden bone collections: none is drawn
    data = rig.data
    assert len(data.bones) == len(bones.bone_names(leafy.parents)) + leafy.leaves.count
    hidden = {c.name for c in data.collections if not c.is_visible}
    assert hidden == {c.name for c in data.collections} == {"Branches", "Leaves"}
    assert all(len(b.collections) > 0 and not any(c.is_visible for c in b.collections) for b in data.bones)
    assert {b.name for b in data.collections["Branches"].bones} == set(bones.bone_names(leafy.parents))

    # Solid view: the leaf material shows the leaves' median colour (linear), the bark its ramp's middle
    leaf = built["leaves"].data.materials[0]
    want = srgb_to_linear(np.median(leafy.leaves.colour, axis=0))
    got = np.array(leaf.diffuse_color[:3])
    assert got == pytest.approx(want, abs=0.01)
    assert got[1] > 1.5 * max(got[0], got[2])                      # green, not grey
    bark = built["material"]
    ramp = next(n for n in bark.node_tree.nodes if n.type == "VALTORGB").color_ramp.elements
    middle = 0.5 * (np.array(ramp[0].color[:3]) + np.array(ramp[-1].color[:3]))
    assert np.array(bark.diffuse_color[:3]) == pytest.approx(middle, abs=0.005)
    assert bark.diffuse_color[0] > bark.diffuse_color[2]           # a brown, warmer than it is blue


def test_replacing_a_tree_keeps_it_unselected_with_hidden_bones(leafy):
    build.build_tree(bpy.context, leafy, "Again")
    built = build.build_tree(bpy.context, leafy, "Again", replace=True)
    assert not any(ob.select_get() for ob in bpy.context.view_layer.objects)
    assert all(not any(c.is_visible for c in b.collections) for b in built["armature"].data.bones)


def test_leaves_are_translucent_in_renders_and_plain_principled_for_exporters(leafy):
    """EEVEE and Cycles read outputs where the leaf's Principled BSDF is mixed with a Translucent
    BSDF of its colour (a backlit crown glows), cut out by the leaf's alpha; the output for ALL,
    which FBX, glTF and USD read, has the Principled BSDF on it directly."""
    from tree_from_video.operators.scene import materials
    built = build.build_tree(bpy.context, leafy, "Glow")
    leaf = built["leaves"].data.materials[0]
    outs = {n.target: n for n in leaf.node_tree.nodes if n.type == "OUTPUT_MATERIAL"}
    assert set(outs) == {"ALL", "EEVEE", "CYCLES"}
    assert outs["ALL"].inputs["Surface"].links[0].from_node.type == "BSDF_PRINCIPLED"
    for target in ("EEVEE", "CYCLES"):
        cut = outs[target].inputs["Surface"].links[0].from_node
        assert cut.type == "MIX_SHADER" and cut.inputs[0].links[0].from_socket.name == "Alpha"
        assert cut.inputs[1].links[0].from_node.type == "BSDF_TRANSPARENT"
        lit = cut.inputs[2].links[0].from_node
        assert lit.inputs[0].default_value == pytest.approx(materials.LEAF_TRANSLUCENCY)
        assert {lit.inputs[1].links[0].from_node.type, lit.inputs[2].links[0].from_node.type} == \
            {"BSDF_PRINCIPLED", "BSDF_TRANSLUCENT"}


def test_the_bark_takes_the_colour_the_video_gave_it(leafy):
    """A tree whose ``meta["bark_colour"]`` says grey bark gets a grey ramp centred on it."""
    import copy
    tree = copy.copy(leafy)
    tree.meta = dict(leafy.meta, bark_colour={"mode": "albedo", "colour": [0.5, 0.5, 0.5], "source": "albedo",
                                              "why": "test"})
    bark = build.build_tree(bpy.context, tree, "Grey")["material"]
    want = srgb_to_linear(np.array([0.5, 0.5, 0.5]))
    assert np.array(bark.diffuse_color[:3]) == pytest.approx(want, abs=0.005)
