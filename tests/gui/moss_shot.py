"""GUI run (issue 36): the moss of a photo of bark (tests/bark_photos.py, seed 5) on the upper side
of a reconstructed tree's limbs and the north side of its trunk: *Moss* 0 beside *Moss* 2, seen from
the north and above in Material Preview in the real Blender. For the README's picture.

    real-blender gui-shot OUT.png --size 1600x900 --wait 45 -- \
        blender --factory-startup --python tests/gui/moss_shot.py
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import empty_stage, show_material, side_by_side  # noqa: E402

empty_stage()
from bark_photos import bark_photo  # noqa: E402

from tree_from_video.core.detail.bark_photo import BarkPhotoParams, bark_maps  # noqa: E402

from trees import broad_tree  # noqa: E402

photo, _, _ = bark_photo(5, size=(720, 960))
bare = bark_maps([photo], BarkPhotoParams(scale_cm=30.0, moss=0.0))
mossy = bark_maps([photo], BarkPhotoParams(scale_cm=30.0, moss=2.0))
tree = broad_tree(24)
side_by_side(tree, 1.4, ("Moss 0", {"bark_maps": bare}), ("Moss 2", {"bark_maps": mossy}))
print(f"moss cover: {bare.moss[1]:.1%} and {mossy.moss[1]:.1%} of the tile", flush=True)

# from the north (+Y) and 35° above, looking south at the first forks of both trees
show_material((0.7, 0.0, 3.2), 6.5, rotation=(0.0, 0.0, 0.485, 0.875))
