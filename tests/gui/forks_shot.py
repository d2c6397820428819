"""GUI run (issue 36 part 3): the broad sample's true tree built twice in the real Blender, with
*Forks* Overlap (left: every branch its own tube, starting inside its parent) and Joined (right:
one closed surface), Material Preview, close on its first forks, posed mid-sway. For the README.

    real-blender gui-shot OUT.png --size 1400x900 --wait 30 -- \
        blender --factory-startup --python tests/gui/forks_shot.py
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import empty_stage, show_material, side_by_side  # noqa: E402

empty_stage()
from tree_from_video.core import bones  # noqa: E402

from trees import broad_tree  # noqa: E402

tree = broad_tree(48)
GAP = 1.1
overlap, joined = side_by_side(tree, GAP, ("Overlap", {"forks": "overlap"}), ("Joined", {"forks": "joined"}))
edges = bones.bone_edges(tree.parents)
n_out = np.bincount(edges[:, 0], minlength=len(tree.parents))
first = int(np.flatnonzero(n_out >= 2)[0])
focus = tree.nodes3d[0, first].astype(float)
print(f"first fork at node {first}, {focus.round(3)} m; polygons: overlap {len(overlap['mesh'].data.polygons)}, "
      f"joined {len(joined['mesh'].data.polygons)}", flush=True)


show_material((focus[0] + GAP / 2, focus[1], focus[2] + 0.12), 1.6, (0.72, 0.69, 0.03, 0.03),   # from the front,
              frame=20)                                                                         # a little from above
