"""Shared, cached inputs of the generation tests: reconstructed sample trees and their species."""
from __future__ import annotations

import functools
import os

from tree_from_video.core.generate import species

from samples import committed, plain_settings


@functools.lru_cache(maxsize=None)
def source_tree(name: str = "broad"):
    """The committed sample ``name`` reconstructed with default settings (Tree3D, metres)."""
    from tree_from_video.core import pipeline
    folder = committed(name)
    s = plain_settings()
    res = pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s)
    return pipeline.build_3d(res, s, name=name)


@functools.lru_cache(maxsize=None)
def source_model(name: str = "broad"):
    return species.fit_species(source_tree(name), name)
