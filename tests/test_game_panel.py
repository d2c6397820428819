"""The Game Export panel (issue 33 item 7): choosing an engine fills the game settings from the
core's preset; Generate then builds a game tree (LODs, a cut rig, capsules) and keeps its engine
files, and Export writes them beside the tree's file (named after it, the bone texture's JSON
naming its own image); the Unity preset's FBX carries its metres in the FBX unit scale (read from the
FBX's GlobalSettings) where the plain export scales the objects instead."""
import json

import bpy
import pytest
from fbx_reader import child, read_fbx, top

from tree_from_video.core.asset.game import ENGINES

from trees import addon  # noqa: F401  (fixture)

pytestmark = [pytest.mark.blender]


def _unit_scale(path) -> float:
    props = child(top(read_fbx(path), "GlobalSettings"), "Properties70")[0]
    return next(p["props"][4] for p in child(props, "P") if p["props"][0] == b"UnitScaleFactor")


def _export():
    try:
        return bpy.ops.tree_video.export("EXEC_DEFAULT")
    except RuntimeError as exc:
        raise AssertionError(str(exc)) from None


def test_an_engine_preset_builds_and_exports_a_game_tree(addon, tmp_path):
    p = addon
    p.game_engine = "UNREAL"
    u = ENGINES["unreal"]
    assert (p.game_bones, p.game_lods, p.game_collision, p.game_pivot_painter, p.game_bone_texture) == \
        (u["bones"], u["lods"], True, True, False)
    assert p.loop_seconds == u["loop_s"] and p.export_format == "FBX"
    p.game_bones, p.game_bone_texture = 24, True                  # edited after the preset
    p.gen_frames, p.gen_nodes, p.gen_seed = 48, 90, 91
    p.loop_seconds = 1.0
    assert bpy.ops.tree_video.generate() == {"FINISHED"}
    coll = next(c for c in bpy.data.collections if c.name.startswith("broad"))
    rig = next(o for o in coll.all_objects if o.type == "ARMATURE")
    assert len(rig.data.bones) <= 24
    names = sorted(o.name for o in coll.all_objects if o.type == "MESH")
    assert [n for n in names if "_LOD" in n] == [f"{coll.name}_LOD{k}" for k in range(3)]
    assert any(n.startswith("UCP_") for n in names)
    p.export_scope, p.export_tree = "PICK", coll
    p.output_dir, p.export_name = str(tmp_path), "oak"
    assert _export() == {"FINISHED"}
    written = sorted(f.name for f in tmp_path.iterdir())
    assert written == sorted(["oak.fbx", "oak_pivot_pos_index.exr", "oak_xaxis_extent.png", "oak_pivot_painter.json",
                              "oak_bone_anim.exr", "oak_bone_anim.json", "oak_collision.json"])
    doc = json.load(open(tmp_path / "oak_bone_anim.json"))
    assert doc["image"] == "oak_bone_anim.exr" and doc["loop"] and len(doc["bones"]) == len(rig.data.bones)
    pp2 = json.load(open(tmp_path / "oak_pivot_painter.json"))          # its textures by their written names
    assert pp2["files"] == ["oak_pivot_pos_index.exr", "oak_xaxis_extent.png"]
    # a second export refuses to overwrite the engine files too, naming one
    (tmp_path / "oak.fbx").unlink()
    with pytest.raises(AssertionError, match="oak_"):
        _export()
    # the Unity preset's FBX units
    plain = _unit_scale(tmp_path / "oak.fbx") if (tmp_path / "oak.fbx").exists() else None
    assert plain is None
    p.overwrite = True
    p.game_engine = "NONE"
    p.export_format = "FBX"
    assert _export() == {"FINISHED"}
    blender_scale = _unit_scale(tmp_path / "oak.fbx")
    p.game_engine = "UNITY"
    assert p.game_bone_texture and not p.game_pivot_painter
    assert _export() == {"FINISHED"}
    # Blender's default keeps the FBX scale 1 and scales the objects ×100; Unity's preset puts the
    # metres into the FBX's unit scale (centimetres × 100), so Unity imports the objects at scale 1
    assert blender_scale == pytest.approx(1.0) and _unit_scale(tmp_path / "oak.fbx") == pytest.approx(100.0)
