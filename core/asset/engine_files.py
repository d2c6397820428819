"""The engine files of a game tree in one place (issue 33): Pivot Painter 2's textures and JSON, the
bone-animation texture and its JSON, the collision capsules' JSON, as ``{file name: bytes}`` the
batch writes into its output folder and the panel keeps in the tree's collection until Export
writes them beside the tree's file (each name prefixed with the file's stem there: :func:`with_prefix`)."""
from __future__ import annotations

import json

from ..fileio import json_bytes
from ..tree3d import Tree3D
from . import TreeAsset
from .bone_texture import bone_files, bone_texture
from .collision import collision_files
from .game import GameSettings
from .pivot_painter import pivot_files


def engine_files(tree: Tree3D, asset: TreeAsset, game: GameSettings) -> dict[str, bytes]:
    """What ``game`` asks for of ``asset`` (made from ``tree`` with ``pivots`` and ``collision`` as
    ``game`` says), by file name."""
    out: dict[str, bytes] = {}
    if game.pivot_painter:
        assert asset.pivots is not None, "the asset was made without its Pivot Painter elements"
        out.update(pivot_files(asset.pivots))
    if game.bone_texture:
        out.update(bone_files(bone_texture(tree, asset.rig)))
    if game.collision:
        out.update(collision_files(tree.name, asset.capsules))
    return out


def with_prefix(files: dict[str, bytes], prefix: str) -> dict[str, bytes]:
    """``files`` each named ``prefix + name``; a JSON naming one of them (the bone texture's
    ``image``, Pivot Painter's and the impostor's ``files``) names the renamed file."""
    def renamed(v):
        if isinstance(v, str):
            return prefix + v if v in files else v
        if isinstance(v, list):
            return [renamed(x) for x in v]
        if isinstance(v, dict):
            return {k: renamed(x) for k, x in v.items()}
        return v
    out = {}
    for name, data in files.items():
        if name.endswith(".json"):
            doc = json.loads(data)
            new = {k: renamed(v) if k in ("image", "files") else v for k, v in doc.items()}
            if new != doc:
                data = json_bytes(new)
        out[prefix + name] = data
    return out


def engine_line(asset: TreeAsset, game: GameSettings) -> str:
    """What the engine files hold, for a report line."""
    parts = []
    if game.pivot_painter and asset.pivots is not None:
        parts.append(f"Pivot Painter {len(asset.pivots.parent)} elements in {asset.pivots.doc['levels']} levels")
    if game.bone_texture:
        parts.append(f"bone texture {len(asset.rig.names)} bones")
    if game.collision:
        parts.append(f"{len(asset.capsules)} capsules")
    return ", ".join(parts)
