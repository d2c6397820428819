"""What a game export asks for (issue 33), one set of defaults the CLI, the panel and the API read:
the bone budget, the levels of detail, and the engine files written beside the exports (Pivot
Painter 2 textures, the bone-animation texture, collision capsules). The loop's length lives in
:class:`core.loop.LoopSettings`.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..params import param
from .lod import MAX_LODS


@dataclass
class GameSettings:
    """``bones`` the most bones the rig keeps (0: every bone; :mod:`.budget`); ``lods`` levels of
    detail LOD0..LOD(k−1) in the exports (1: the film meshes, :mod:`.lod`); ``collision`` capsules
    ``UCP_<tree>_NN`` for the trunk and main limbs (:mod:`.collision`); ``pivot_painter`` Unreal
    Pivot Painter 2 textures (:mod:`.pivot_painter`); ``bone_texture`` the motion as a
    bone-animation texture (:mod:`.bone_texture`); ``viewer`` the web viewer page (:mod:`.web_viewer`)."""

    bones: int = param(0, 0, 100000, what="--bones")
    lods: int = param(1, 1, MAX_LODS, what="--lods")
    collision: bool = False
    pivot_painter: bool = False
    bone_texture: bool = False
    viewer: bool = False

    def files(self) -> list[str]:
        """The engine files these settings write beside the exports (names in the output folder)."""
        from .bone_texture import FILES as BONE_FILES
        from .collision import FILE as COLLISION_FILE
        from .pivot_painter import FILES as PP2_FILES
        from .web_viewer import FILES as VIEWER_FILES
        return ((list(PP2_FILES) if self.pivot_painter else []) + (list(BONE_FILES) if self.bone_texture else [])
                + ([COLLISION_FILE] if self.collision else []) + (list(VIEWER_FILES) if self.viewer else []))

    @property
    def bone_budget(self) -> int | None:
        """The budget :func:`core.asset.tree_asset` takes (None: every bone)."""
        return int(self.bones) if self.bones else None
