"""A game tree in the panel's workflow (issue 33): the build settings the Game Export panel gives
(bone budget, LODs, Pivot Painter UVs, collision capsules) and the engine files made with the tree
(:func:`core.asset.engine_files.engine_files`), kept in its collection as the ID property
:data:`KEY` ``{file name: bytes}`` until Export writes them beside the tree's file as
``<file stem>_<name>`` (saved with the .blend, removed with the tree)."""
from __future__ import annotations

import os

from ...core.asset.engine_files import engine_files, with_prefix
from ...core.asset.game import GameSettings

KEY = "_tree_video_engine_files"
#: marks a tree built for a game engine: its GLB is written packed for engines
GAME_KEY = "_tree_video_game"


def game_settings(props) -> GameSettings:
    """The Game Export panel's :class:`GameSettings` (``scene.tree_video``): what a tree is built
    with, what Export writes beside it."""
    engine = "" if props.game_engine == "NONE" else props.game_engine.lower()
    return GameSettings(bones=int(props.game_bones), lods=int(props.game_lods), collision=bool(props.game_collision),
                        pivot_painter=bool(props.game_pivot_painter), bone_texture=bool(props.game_bone_texture),
                        impostor=bool(props.game_impostor), engine=engine, loop_s=float(props.loop_seconds))


def build_kwargs(game: GameSettings) -> dict:
    """:func:`.build.build_tree`'s keywords for ``game``."""
    return {"bone_budget": game.bone_budget, "lods": int(game.lods), "pivots": bool(game.pivot_painter),
            "collision": bool(game.collision), "impostor": bool(game.impostor)}


def built_engine_files(built: dict, tree, game: GameSettings) -> dict[str, bytes]:
    """``game``'s engine files of a tree :func:`.build.build_tree` built: the core's, and the
    impostor's that Blender rendered, by file name."""
    files = engine_files(tree, built["asset"], game)
    files.update(built.get("impostor") or {})
    return files


def keep_engine_files(built: dict, tree, game: GameSettings) -> int:
    """Make ``game``'s engine files of the built tree and keep them in its collection; returns how
    many (0: none asked for, nothing kept)."""
    if game.is_game:
        built["collection"][GAME_KEY] = True
    files = built_engine_files(built, tree, game)
    if files:
        built["collection"][KEY] = {name: data for name, data in files.items()}
    return len(files)


def kept_files(coll, stem: str) -> dict[str, bytes]:
    """The engine files kept with tree ``coll`` as they are written beside ``<stem>.<ext>``:
    ``{"<stem>_<name>": bytes}`` (a bone texture's JSON names its image so)."""
    kept = coll.get(KEY) if coll is not None else None
    return with_prefix({name: bytes(data) for name, data in kept.items()}, f"{stem}_") if kept else {}


def kept_paths(coll, path: str) -> list[str]:
    """Where Export writes ``coll``'s engine files when its file is ``path`` (names only: the panel
    asks on every redraw)."""
    kept = coll.get(KEY) if coll is not None else None
    stem = os.path.splitext(os.path.basename(path))[0]
    return [os.path.join(os.path.dirname(path), f"{stem}_{name}") for name in (kept or {}).keys()]


def is_game_tree(coll) -> bool:
    """Whether tree ``coll`` was built with game settings (:func:`keep_engine_files`)."""
    try:
        return bool(coll.get(GAME_KEY))
    except ReferenceError:
        return False
