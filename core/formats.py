"""The product's output formats, in one registry the CLI, the batch outputs, the panel and the API
all read (issue 33: five places kept their own table): each format's key, its batch flag and file
name, the extensions a path may end in, the writer that makes it, and the words the panel and
``--help`` show. Pure data, no bpy.

Interchange formats (FBX, glTF, USD) are what the panel's Export writes and what ``api.export``
picks by extension; the batch also writes a .blend and a preview image.
"""
from __future__ import annotations

import os
from dataclasses import dataclass


@dataclass(frozen=True)
class OutputFormat:
    """One output format.

    ``key`` the panel's enum identifier ("FBX"); ``flag`` the batch option without its dashes
    ("fbx") and the key of the batch's ``wanted``/``written`` dicts; ``file`` the batch's file name
    in ``--out``; ``extensions`` the endings a path of this format may have (the first is what the
    panel writes); ``writer`` the function of ``operators/scene/export.py`` that writes it (None:
    not an interchange export); ``label`` and ``description`` what the panel shows; ``help`` the
    batch option's help (``{file}`` stands for the file name)."""

    key: str
    flag: str
    file: str
    extensions: tuple[str, ...]
    writer: str | None
    label: str
    description: str
    help: str
    needs_usd: bool = False

    @property
    def extension(self) -> str:
        """What the panel names its files with (".fbx")."""
        return self.extensions[0]

    @property
    def interchange(self) -> bool:
        """An export for other software (the panel's Format, ``api.export``)."""
        return self.writer is not None


FORMATS: tuple[OutputFormat, ...] = (
    OutputFormat("FBX", "fbx", "tree.fbx", (".fbx",), "export_fbx", "FBX",
                 "Armature + skinned mesh, baked animation (game engines, Maya, Unreal)",
                 "write DIR/{file} (armature + skinned mesh, baked animation)"),
    OutputFormat("USD", "usd", "tree.usdc", (".usdc", ".usd", ".usda"), "export_usd", "USD",
                 "UsdSkel skeleton and animation (needs a Blender built with USD)",
                 "write DIR/{file} (needs a Blender built with USD)", needs_usd=True),
    OutputFormat("GLB", "gltf", "tree.glb", (".glb",), "export_gltf", "glTF",
                 "Binary glTF with skin and animation from t = 0 (web, Godot, Unity)",
                 "write DIR/{file} (glTF binary, animation from t = 0)"),
    OutputFormat("BLEND", "blend", "tree.blend", (".blend",), None, "Blender",
                 "The scene with the animated tree, saved compressed",
                 "write DIR/{file} (the scene with the animated tree)"),
    OutputFormat("PREVIEW", "preview", "preview.png", (".png",), None, "Preview",
                 "Front and side renders of frame 1 (Workbench)",
                 "write DIR/{file} (front and side renders of frame 1)"),
)


def interchange() -> tuple[OutputFormat, ...]:
    """The formats the panel's Export and ``api.export`` write (FBX, glTF, USD), panel order."""
    order = ("FBX", "GLB", "USD")
    return tuple(sorted((f for f in FORMATS if f.interchange), key=lambda f: order.index(f.key)))


def by_key(key: str) -> OutputFormat:
    """The format of the panel's key ("GLB"); KeyError names the known ones."""
    for f in FORMATS:
        if f.key == key:
            return f
    raise KeyError(f"unknown output format {key!r}; known: {', '.join(f.key for f in FORMATS)}")


def by_flag(flag: str) -> OutputFormat:
    """The format of a batch flag ("gltf")."""
    for f in FORMATS:
        if f.flag == flag:
            return f
    raise KeyError(f"unknown output flag {flag!r}; known: {', '.join(f.flag for f in FORMATS)}")


def for_path(path: str) -> OutputFormat | None:
    """The interchange format a file name asks for by its extension (None: none does)."""
    ext = os.path.splitext(path)[1].lower()
    return next((f for f in interchange() if ext in f.extensions), None)


def interchange_extensions() -> list[str]:
    """Every extension :func:`for_path` knows, sorted."""
    return sorted(e for f in interchange() for e in f.extensions)
