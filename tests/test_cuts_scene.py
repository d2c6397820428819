"""Tree-cuts in Blender (issue 36 part 3): Save Cut keeps the bones selected on a tree's rig (and
every bone beyond them) with the very mesh Blender shows for them; Generate Tree places the panel's
cut where its base fits; Place Cut grows the selected generated tree again with the cut on the
branch at the 3D cursor, in place. The placed cut's bones in the rig are the saved ones (lengths
and angles within 1 %)."""
import numpy as np
import pytest
from test_cuts import bone_angles

from tree_from_video.core.tree_cut import bone_lengths, cut_from_tree, load_cut

from trees import (
    broad_tree,
    empty_scene,  # noqa: F401  (autouse fixture)
    registered,  # noqa: F401  (autouse fixture)
)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]


def _kept_tree():
    """The sample's true tree built and kept in the file as Reconstruct keeps it; its rig active."""
    import bpy

    from tree_from_video.operators.scene import stored
    from tree_from_video.operators.scene.build import build_tree
    tree = broad_tree(frames=4)
    built = build_tree(bpy.context, tree, "Kept", leaves=False)
    stored.store_tree(built["collection"], tree, "/videos/kept.mp4")
    rig = built["armature"]
    bpy.context.view_layer.objects.active = rig
    return tree, built


def _select(rig, names):
    from tree_from_video.operators.cut_op import select_bones
    select_bones(rig, names)


def _rest_nodes(rig, tree_nodes: np.ndarray, base: int) -> np.ndarray:
    """``(M, 3)`` rest positions (armature space) of ``base`` then ``tree_nodes`` from the rig's bones."""
    b = rig.data.bones
    return np.array([b[f"B{base:03d}"].tail_local if base > 0 else b[f"B{tree_nodes[0]:03d}"].head_local]
                    + [b[f"B{n:03d}"].tail_local for n in tree_nodes], np.float64)


def test_save_cut_keeps_the_selected_branch_and_its_mesh(tmp_path):
    import bpy
    tree, built = _kept_tree()
    rig = built["armature"]
    assert not bpy.ops.tree_video.save_cut.poll()                    # no bone selected yet
    _select(rig, ["B040"])
    path = tmp_path / "limb.npz"
    assert bpy.ops.tree_video.save_cut(filepath=str(path)) == {"FINISHED"}
    cut = load_cut(path)
    want = cut_from_tree(tree, ["B040"])
    assert np.array_equal(cut.source_nodes, want.source_nodes) and cut.n_bones > 1
    assert np.allclose(cut.rest, want.rest, atol=1e-6) and np.allclose(cut.radius, want.radius)
    assert bpy.context.scene.tree_video.gen_cut == str(path)
    # its mesh is the one Blender shows for those bones: every cut vertex on a vertex of the branch
    # mesh (rest, armature space) weighted to one of the cut's bones
    mesh = built["mesh"]
    co = np.array([v.co for v in mesh.data.vertices], np.float64)
    groups = {g.index: g.name for g in mesh.vertex_groups}
    names = {f"B{n:03d}" for n in cut.source_nodes[1:]}
    mine = np.array([any(groups[g.group] in names and g.weight > 0.5 for g in v.groups) for v in mesh.data.vertices])
    base = np.asarray(tree.nodes3d[0][cut.source_nodes[0]], np.float64)
    from scipy.spatial import cKDTree
    d, _ = cKDTree(co[mine] - base).query(cut.mesh.co)
    assert d.max() < 1e-4 and len(cut.mesh.co) == mine.sum()
    # nothing overwritten without Overwrite
    with pytest.raises(RuntimeError, match="exists; tick Overwrite"):
        bpy.ops.tree_video.save_cut(filepath=str(path))
    assert bpy.ops.tree_video.save_cut(filepath=str(path), overwrite=True) == {"FINISHED"}


def test_generate_and_place_cut_in_blender(tmp_path):
    import bpy
    tree, built = _kept_tree()
    _select(built["armature"], ["B040"])
    path = tmp_path / "limb.npz"
    assert bpy.ops.tree_video.save_cut(filepath=str(path)) == {"FINISHED"}
    cut = load_cut(path)
    p = bpy.context.scene.tree_video
    p.species_source, p.species_name, p.envelope_source = "LIBRARY", "broad", "CIRCLE"
    p.gen_frames, p.gen_nodes, p.gen_height, p.gen_seed, p.gen_wind = 12, 150, 8.0, 19, 0.0
    p.build_leaves = False
    bpy.context.scene.cursor.location = (6.0, 1.0, 0.0)
    assert bpy.ops.tree_video.generate() == {"FINISHED"}
    coll = bpy.data.collections["broad 19"]
    rig = next(o for o in coll.objects if o.type == "ARMATURE")
    from tree_from_video.operators.scene import stored
    assert [c["at"] for c in stored.grown_cuts(coll)] == [None]
    kept = stored.kept_tree(coll)
    (info,) = kept.meta["cuts"]
    nodes = np.arange(info["first_node"], info["first_node"] + info["bones"])
    L = bone_lengths(cut.parents, _rest_nodes(rig, nodes, info["base_node"]))[1:]
    assert np.abs(L / cut.bone_lengths() - 1).max() < 0.01

    # Place Cut: the cursor on a branch of that tree (world), the tree grown again in place, as it
    # grew: the panel since turned to another species, height and seed changes nothing
    p.species_name, p.gen_height, p.gen_seed = "sparse", 5.0, 3
    rig.rotation_euler = (0.0, 0.0, 0.5)
    bpy.context.view_layer.update()
    local = np.array([0.6, -0.2, 5.0])
    world = np.array(rig.matrix_world) @ np.append(local, 1.0)
    bpy.context.scene.cursor.location = world[:3]
    bpy.context.view_layer.objects.active = rig
    assert bpy.ops.tree_video.place_cut.poll()
    assert bpy.ops.tree_video.place_cut() == {"FINISHED"}
    coll = bpy.data.collections["broad 19"]
    rig = next(o for o in coll.objects if o.type == "ARMATURE")
    assert np.allclose(rig.location, (6.0, 1.0, 0.0)) and np.isclose(rig.rotation_euler[2], 0.5)
    assert len([c for c in bpy.data.collections if c.name.startswith("broad 19")]) == 1
    kept = stored.kept_tree(coll)
    assert kept.meta["species"] == "broad" and kept.meta["seed"] == 19
    assert np.isclose(max(kept.meta["envelope"]["z"]), 8.0, atol=0.01)
    fit, at = kept.meta["cuts"]
    assert at["placed"] == "at" and np.allclose(at["at"], local, atol=1e-4)
    rest = kept.nodes3d[0].astype(np.float64)
    grown = (kept.meta.get("twigs") or {}).get("first_node", kept.n_nodes)      # twigs come after the cuts
    own = np.setdiff1d(np.arange(grown), np.arange(at["first_node"], at["first_node"] + at["bones"]))
    nearest = own[np.argsort(np.linalg.norm(rest[own] - local, axis=1))[:1 + at["regrown"]]]
    assert at["base_node"] in nearest
    for info in (fit, at):
        nodes = np.arange(info["first_node"], info["first_node"] + info["bones"])
        pos = _rest_nodes(rig, nodes, info["base_node"])
        L = bone_lengths(cut.parents, pos)[1:]
        assert np.abs(L / cut.bone_lengths() - 1).max() < 0.01
        a_new = bone_angles(cut.parents, pos)[1:]
        a_old = bone_angles(cut.parents, cut.rest)[1:]
        ok = np.isfinite(a_old)
        assert np.abs(a_new[ok] - a_old[ok]).max() < 0.01 * np.abs(a_old[ok]).max()


def test_save_cut_from_a_generated_tree(tmp_path):
    """A tree made by Generate Tree keeps its rest in the file: Save Cut works on it as on a
    reconstruction, and the cut is the generated tree's branch."""
    import bpy

    from tree_from_video.operators.scene import stored
    p = bpy.context.scene.tree_video
    p.species_source, p.species_name, p.envelope_source = "LIBRARY", "sparse", "CIRCLE"
    p.gen_frames, p.gen_nodes, p.gen_height, p.gen_seed = 6, 90, 6.0, 43
    p.build_leaves = False
    assert bpy.ops.tree_video.generate() == {"FINISHED"}
    coll = bpy.data.collections["sparse 43"]
    rig = next(o for o in coll.objects if o.type == "ARMATURE")
    kept = stored.kept_tree(coll)
    assert kept.n_frames == 1                                   # its rest only: a few kB in the .blend
    bpy.context.view_layer.objects.active = rig
    _select(rig, ["B010"])
    assert bpy.ops.tree_video.save_cut(filepath=str(tmp_path / "g.npz")) == {"FINISHED"}
    cut = load_cut(tmp_path / "g.npz")
    want = cut_from_tree(kept, ["B010"])
    assert np.array_equal(cut.source_nodes, want.source_nodes) and np.allclose(cut.rest, want.rest)
    rest = _rest_nodes(rig, cut.source_nodes[1:], int(cut.source_nodes[0]))
    assert np.allclose(rest - rest[0], cut.rest, atol=1e-5)         # the rig's bones are the cut's
