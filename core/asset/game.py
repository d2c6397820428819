"""What a game export asks for (issue 33), one set of defaults the CLI, the panel and the API read:
the bone budget, the levels of detail, and the engine files written beside the exports (Pivot
Painter 2 textures, the bone-animation texture, collision capsules). The loop's length lives in
:class:`core.loop.LoopSettings`.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from ..params import param
from .lod import MAX_LODS


@dataclass
class GameSettings:
    """``bones`` the most bones the rig keeps (0: every bone; :mod:`.budget`); ``lods`` levels of
    detail LOD0..LOD(k−1) in the exports (1: the film meshes, :mod:`.lod`); ``collision`` capsules
    ``UCP_<tree>_NN`` for the trunk and main limbs (:mod:`.collision`); ``pivot_painter`` Unreal
    Pivot Painter 2 textures (:mod:`.pivot_painter`); ``bone_texture`` the motion as a
    bone-animation texture (:mod:`.bone_texture`); ``viewer`` the web viewer page (:mod:`.web_viewer`);
    ``impostor`` the hemi-octahedral atlas and its crossed-billboard card as the last LOD
    (:mod:`.impostor`);
    ``engine`` the preset these came from ("": none; :data:`ENGINES`), which also sets the FBX's
    axes and units (:meth:`fbx_options`); ``loop_s`` and ``formats`` (batch flags, e.g. "fbx") what
    the preset asks for besides."""

    bones: int = param(0, 0, 100000, what="--bones")
    lods: int = param(1, 1, MAX_LODS, what="--lods")
    collision: bool = False
    pivot_painter: bool = False
    bone_texture: bool = False
    viewer: bool = False
    impostor: bool = False
    engine: str = param("", choices=("", "unreal", "unity", "godot", "web"), what="--engine")
    loop_s: float = 0.0
    formats: tuple[str, ...] = field(default_factory=tuple)

    def files(self) -> list[str]:
        """The engine files these settings write beside the exports (names in the output folder)."""
        from .bone_texture import FILES as BONE_FILES
        from .collision import FILE as COLLISION_FILE
        from .impostor import FILES as IMPOSTOR_FILES
        from .pivot_painter import FILES as PP2_FILES
        from .web_viewer import FILES as VIEWER_FILES
        return ((list(PP2_FILES) if self.pivot_painter else []) + (list(BONE_FILES) if self.bone_texture else [])
                + ([COLLISION_FILE] if self.collision else []) + (list(IMPOSTOR_FILES) if self.impostor else [])
                + (list(VIEWER_FILES) if self.viewer else []))

    @property
    def is_game(self) -> bool:
        """Anything asked for a game engine (then the GLB is packed for engines)."""
        return bool(self.engine or self.bones or self.lods > 1 or self.pivot_painter or self.bone_texture
                    or self.collision or self.viewer or self.impostor)

    @property
    def bone_budget(self) -> int | None:
        """The budget :func:`core.asset.tree_asset` takes (None: every bone)."""
        return int(self.bones) if self.bones else None


#: what each engine gets (issue 33 item 7; docs: Unreal's FBX import, Pivot Painter 2 and collision
#: names; Unity's LOD suffixes and FBX units; Godot's glTF import, its *_loop name and its own LODs;
#: three.js for the web): formats, bones, LODs, loop seconds and the engine files
ENGINES: dict[str, dict] = {
    # (the impostor is left to the user: its 128 Workbench renders cost ~10 s a tree, a forest's minutes)
    "unreal": dict(formats=("fbx",), bones=64, lods=3, loop_s=10.0, collision=True, pivot_painter=True),
    "unity": dict(formats=("fbx",), bones=64, lods=3, loop_s=10.0, collision=False, bone_texture=True),
    # Godot generates its own LODs from a glTF (meshoptimizer) and loops an animation named *_loop
    "godot": dict(formats=("gltf",), bones=64, lods=1, loop_s=10.0),
    "web": dict(formats=("gltf",), bones=32, lods=2, loop_s=10.0, bone_texture=True, viewer=True),
}

#: FBX exporter options per engine (Blender's io_scene_fbx): Unreal reads Blender's defaults; Unity
#: gets "FBX Units Scale" (the metres in the file's UnitScaleFactor, the objects at scale 1: the
#: setting Blender users pick so Unity imports no ×100 object scale)
FBX_OPTIONS: dict[str, dict] = {"unreal": {}, "unity": {"apply_scale_options": "FBX_SCALE_UNITS"}}


def preset(engine: str, **given) -> GameSettings:
    """The :class:`GameSettings` of ``engine`` (:data:`ENGINES`; "" for none), with the ``given``
    settings (those not None) winning over the preset's."""
    base = dict(ENGINES.get(engine, {}))
    base.update({k: v for k, v in given.items() if v is not None})
    names = {f.name for f in fields(GameSettings)}
    bad = sorted(set(base) - names)
    if bad:
        raise ValueError(f"unknown game setting {bad[0]!r}")
    return replace(GameSettings(engine=engine), **base)


def fbx_options(engine: str) -> dict:
    """The FBX exporter options ``engine`` needs (none without one)."""
    return dict(FBX_OPTIONS.get(engine, {}))
