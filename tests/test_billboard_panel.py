"""The panel's Save Billboard (issue 36 part 2): the selected tree's front at rest written as the
batch writes it — alpha the tree's silhouette (IoU ≥ 0.98 where the mesh covers a pixel clearly),
the json's origin on the tree's base wherever the tree stands — and nothing overwritten without
Overwrite."""
import json

import bpy
import cv2
import pytest
from test_billboard import mesh_silhouette

from tree_from_video.core.generate import envelopes, growth, species
from tree_from_video.core.tree3d import save_tree

from trees import empty_scene, registered  # noqa: F401  (autouse fixtures)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]


def test_save_billboard_is_the_trees_silhouette(tmp_path):
    from tree_from_video.operators.scene.build import build_tree
    model = species.load_species(species.species_library()["sparse"])
    tree = growth.grow_tree(model, envelopes.topiary("circle", 6.0),
                            growth.GrowParams(seed=29, n_frames=2, node_budget=120, leaf_density=0.0))
    save_tree(tmp_path / "tree3d.npz", tree)
    assert not bpy.ops.tree_video.save_billboard.poll()             # no tree in the file yet
    built = build_tree(bpy.context, tree, "Lone", leaves=False)
    rig = built["armature"]
    rig.location = (4.0, 2.0, 0.0)                 # a tree standing away from the origin
    bpy.context.view_layer.update()
    bpy.context.view_layer.objects.active = rig
    assert bpy.ops.tree_video.save_billboard(directory=str(tmp_path), px=384) == {"FINISHED"}
    doc = json.loads((tmp_path / "billboard.json").read_text())
    rgba = cv2.imread(str(tmp_path / "billboard.png"), cv2.IMREAD_UNCHANGED)
    assert max(rgba.shape[:2]) == 384 and rgba.shape[2] == 4
    # the json's origin is the tree's base: the silhouette drawn from the tree's own frame lands on it
    cov = mesh_silhouette(str(tmp_path), doc, leaves=False)
    alpha, sil = rgba[..., 3] >= 128, cov >= 0.5
    sure = (cov <= 0.2) | (cov >= 0.8)
    iou = (alpha & sil & sure).sum() / ((alpha | sil) & sure).sum()
    print(f"\nSave Billboard: alpha vs the mesh's silhouette IoU {iou:.4f} where clear")
    assert iou >= 0.98
    with pytest.raises(RuntimeError, match="exists"):
        bpy.ops.tree_video.save_billboard(directory=str(tmp_path), px=384)
    assert bpy.ops.tree_video.save_billboard(directory=str(tmp_path), px=128, overwrite=True) == {"FINISHED"}
    assert max(cv2.imread(str(tmp_path / "billboard.png"), cv2.IMREAD_UNCHANGED).shape[:2]) == 128
