"""The panel's *Bark Image*: the bark tile made from it (:mod:`core.detail.bark_photo`), once per
photo and settings (a forest's trees, a second Reconstruct and a Generate reuse it), for
:func:`.build.build_tree`'s ``bark_maps``."""
from __future__ import annotations

import os

import bpy

from ...core.detail.bark_photo import BarkMaps, BarkPhotoParams, bark_maps, bark_photo_files, read_bark_photo
from ...core.errors import InputError

_CACHE: dict = {}


def panel_bark(props) -> BarkMaps | None:
    """The bark tile of the panel's *Bark Image* (a photo, or a folder of photos of the bark) with its
    *Moss*, *Lichen* and *Bark Scale*; None when no image is set; :class:`InputError` (one line) for
    a missing or unfit photo."""
    path = bpy.path.abspath(props.bark_image.strip()) if props.bark_image.strip() else ""
    if not path:
        return None
    if not os.path.exists(path):
        raise InputError(f"bark image '{props.bark_image}' does not exist; pick a close-up photo of the bark (or "
                         "a folder of them) or clear the field for the procedural bark")
    files = bark_photo_files(path)
    params = BarkPhotoParams(moss=float(props.bark_moss), lichen=float(props.bark_lichen),
                             scale_cm=float(props.bark_scale))
    key = (tuple((f, os.path.getmtime(f)) for f in files), params.moss, params.lichen, params.scale_cm)
    if key not in _CACHE:
        _CACHE.clear()
        _CACHE[key] = bark_maps([read_bark_photo(f) for f in files], params)
    return _CACHE[key]


def species_bark(props, model) -> BarkMaps | None:
    """The panel's bark for trees of ``model``: its *Bark Image*'s (:func:`panel_bark`), else the
    species' own bark from photos (``model.bark_dir``), else None (procedural)."""
    maps = panel_bark(props)
    if maps is None and model is not None and getattr(model, "bark_dir", None):
        from ...core.detail.bark_photo import read_bark_files
        maps = read_bark_files(model.bark_dir)
    return maps
