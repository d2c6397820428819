"""A USD export opens elsewhere: the leaf texture it references is written beside it, under a safe
name, and every ``pxr.UsdValidation`` validator that runs (MissingReferenceValidator included)
finds no error; the validator does flag the file once that texture is gone."""
import os

import bpy
import pytest

from tree_from_video import api
from tree_from_video.core.errors import InputError
from tree_from_video.operators.scene import export

from trees import empty_scene  # noqa: F401  (autouse: a fresh scene per test)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]


@pytest.fixture
def leafy():
    tree = api.generate("broad", 1, seed=2, n_frames=12, node_budget=80)[0]
    assert tree.leaves is not None and tree.leaves.count > 0
    built = api.build_tree(bpy.context, tree, "Tree video")            # a name with a space, as users type
    return [o for o in built["collection"].all_objects if o.type in ("ARMATURE", "MESH")]


def test_usd_writes_its_textures_with_safe_names_and_validates(leafy, tmp_path):
    path = tmp_path / "tree.usda"
    if not export.has_usd():
        with pytest.raises(InputError, match="built without USD"):
            export.export_usd(path, leafy)
        assert os.listdir(tmp_path) == []
        return
    names_before = sorted(img.name for img in bpy.data.images)
    export.export_usd(path, leafy)
    assert sorted(img.name for img in bpy.data.images) == names_before          # the .blend's names kept
    from pxr import Sdf, Usd, UsdValidation
    layer = Sdf.Layer.FindOrOpen(str(path))
    refs = sorted({str(a) for a in _asset_paths(layer)})
    assert refs and all(" " not in r for r in refs), refs
    for r in refs:
        assert os.path.isfile(os.path.join(tmp_path, r)), r                     # written beside the file
        assert os.path.getsize(os.path.join(tmp_path, r)) > 100
    assert [r for r in refs if r.startswith("./textures/")] == refs
    stage = Usd.Stage.Open(str(path))
    missing = UsdValidation.ValidationRegistry().GetOrLoadValidatorByName(
        "usdUtilsValidators:MissingReferenceValidator")
    error = UsdValidation.ValidationErrorType.Error
    assert [e.GetMessage() for e in UsdValidation.ValidationContext([missing]).Validate(stage)
            if e.GetType() == error] == []
    from test_exports import _validate_usd
    _validate_usd(stage)                                                        # all that run: no error
    # the validator sees a missing texture (what the export referenced before this fix)
    for r in refs:
        os.remove(os.path.join(tmp_path, r))
    stage = Usd.Stage.Open(str(path))
    flagged = UsdValidation.ValidationContext([missing]).Validate(stage)
    assert any(e.GetType() == error for e in flagged)


def test_existing_texture_is_kept_unless_overwrite(leafy, tmp_path):
    if not export.has_usd():                # Debian's Blender 4.3: one clear error, no file
        with pytest.raises(InputError, match="built without USD"):
            export.export_usd(tmp_path / "a.usdc", leafy)
        assert os.listdir(tmp_path) == []
        return
    export.export_usd(tmp_path / "a.usdc", leafy)
    tex = [os.path.join(tmp_path, "textures", f) for f in os.listdir(tmp_path / "textures")]
    assert len(tex) >= 1
    with open(tex[0], "wb") as fh:
        fh.write(b"mine")
    export.export_usd(tmp_path / "b.usdc", leafy)
    assert open(tex[0], "rb").read() == b"mine"
    export.export_usd(tmp_path / "c.usdc", leafy, overwrite=True)
    assert open(tex[0], "rb").read() != b"mine"


def _asset_paths(layer):
    out = []

    def visit(path):
        spec = layer.GetObjectAtPath(path)
        for attr in getattr(spec, "attributes", ()):
            v = attr.default
            if v is not None and type(v).__name__ == "AssetPath":
                out.append(v.path)
    layer.Traverse(layer.pseudoRoot.path, visit)
    return out


def test_fbx_embeds_the_leaf_texture_and_reimports_with_it(leafy, tmp_path):
    """Issue 32: the FBX dropped the leaf texture (``path_mode`` AUTO embeds nothing), so its leaves
    imported white. Now it is embedded (COPY + embed_textures): the file holds it as a PNG (bpy 5
    writes three PNG signatures with the baked bark's two; Blender 4.3's file shows one, and its
    re-import still finds the bark's images: tests/test_bark_texture.py), nothing is written beside
    it, and re-imported into an empty Blender the leaf material shows its image."""
    path = tmp_path / "tree.fbx"
    export.export_fbx(path, leafy)
    assert open(path, "rb").read().count(b"\x89PNG") >= 1 and os.listdir(tmp_path) == ["tree.fbx"]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.fbx(filepath=str(path))
    images = [n.image for m in bpy.data.materials if m.node_tree is not None and "Leaf" in m.name
              for n in m.node_tree.nodes if n.type == "TEX_IMAGE" and n.image is not None]
    assert len(images) == 1 and images[0].size[0] >= 64 and images[0].packed_file is not None


def test_a_game_tree_exports_to_usd_and_validates(tmp_path):
    """A game tree (24 bones, LOD0..2 under their group, Pivot Painter's second UV set, capsules)
    in USD: the levels are there, the capsules are not (FBX only), every validator finds no error."""
    tree = api.generate("broad", 1, seed=4, n_frames=12, node_budget=80)[0]
    built = api.build_tree(bpy.context, tree, "Game tree", bone_budget=24, lods=3, pivots=True, collision=True)
    from tree_from_video.operators.scene import trees
    objects = trees.tree_objects(built["collection"])
    path = tmp_path / "game.usda"
    if not export.has_usd():
        with pytest.raises(InputError, match="built without USD"):
            export.export_usd(path, objects)
        return
    export.export_usd(path, objects)
    from pxr import Usd, UsdGeom
    stage = Usd.Stage.Open(str(path))
    meshes = [p.GetName() for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert {"Game_tree_LOD0", "Game_tree_LOD1", "Game_tree_LOD2"} <= set(meshes), meshes
    assert not [m for m in meshes if m.startswith("UCP_")]
    from test_exports import _validate_usd
    _validate_usd(stage)
