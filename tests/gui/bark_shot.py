"""GUI run (issue 36): the bark made from a photo of bark (a synthetic close-up with moss and
lichen, tests/bark_photos.py, seed 5) on a reconstructed tree's trunk, Material Preview in the real
Blender, beside the same tree with the procedural rough bark. For the README's picture.

    real-blender gui-shot OUT.png --size 1400x900 --wait 30 -- \
        blender --factory-startup --python tests/gui/bark_shot.py
"""
import os
import sys
import tempfile

import cv2

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import empty_stage, show_material, side_by_side  # noqa: E402

empty_stage()
from bark_photos import bark_photo  # noqa: E402

from tree_from_video.core.detail.bark_photo import BarkPhotoParams, bark_maps  # noqa: E402

from trees import broad_tree  # noqa: E402

photo, _, _ = bark_photo(5, size=(720, 960))
cv2.imwrite(os.path.join(tempfile.gettempdir(), "tfv_bark_photo.jpg"), photo)
maps = bark_maps([photo], BarkPhotoParams(scale_cm=60.0))
tree = broad_tree(24)
side_by_side(tree, 1.0, ("Procedural", {"bark": "rough"}), ("From Photo", {"bark_maps": maps}))
print(f"bark tile: moss {maps.moss[0]:.1%} -> {maps.moss[1]:.1%}, lichen {maps.lichen[0]:.1%} -> {maps.lichen[1]:.1%}",
      flush=True)


show_material((0.5, 0.0, 0.7), 1.9)
