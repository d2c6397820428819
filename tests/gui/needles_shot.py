"""GUI run (issue 35): a conifer's needle sprays against a broadleaf's leaf cards — the same grown
conifer (``api.generate("conifer")``, seed 4) built twice, its clusters as the needle sprays it now
wears (left) and as the broad-leaf clusters it wore before (right), Material Preview in the real
Blender, close enough to see the cards. For the README's picture.

    real-blender gui-shot OUT.png --size 1400x900 --wait 90 -- \\
        blender --factory-startup --python tests/gui/needles_shot.py
"""
import dataclasses
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import empty_stage, show_material  # noqa: E402

empty_stage()
import bpy  # noqa: E402
import numpy as np  # noqa: E402

from tree_from_video import api  # noqa: E402
from tree_from_video.operators.scene import build  # noqa: E402

tree = api.generate("conifer", 1, seed=4, node_budget=220)[0]
before = dataclasses.replace(tree, leaves=dataclasses.replace(tree.leaves, shape="cluster"))
top = float(tree.nodes3d[0][:, 2].max())
gap = 1.15 * float(np.ptp(tree.nodes3d[0][:, 0]) + 1e-3)
a = build.build_tree(bpy.context, tree, "Needle Sprays")
b = build.build_tree(bpy.context, before, "Leaf Cards")
b["armature"].location.x = gap
print(f"conifer: {tree.n_nodes} nodes, {tree.leaves.count} clusters of {tree.leaves.cards} cards, {top:.1f} m",
      flush=True)
show_material((0.5 * gap, 0.0, 0.6 * top), 1.25 * top)
