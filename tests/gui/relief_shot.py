"""GUI run (issue 36 part 3): the broad sample's true tree built twice in the real Blender with
rough bark, *Bark Relief* 0 (left: the relief only in the shading) and 5 cm (right: the bark's
height map in the mesh), close on the trunk, posed mid-sway: Material Preview above, Solid below
(the geometry alone, no normal map). For the README.

    real-blender gui-shot OUT.png --size 1400x900 --wait 30 -- \
        blender --factory-startup --python tests/gui/relief_shot.py
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import empty_stage, show_material, side_by_side  # noqa: E402

empty_stage()

from trees import broad_tree  # noqa: E402

tree = broad_tree(48)
GAP = 0.9
plain, relief = side_by_side(tree, GAP, ("Shaded", {"bark": "rough"}), ("Relief", {"bark": "rough", "relief_cm": 5.0}))
base = tree.nodes3d[0, 0].astype(float)
print(f"polygons: shaded {len(plain['mesh'].data.polygons)}, relief {len(relief['mesh'].data.polygons)}", flush=True)


solid = "--" in sys.argv and "solid" in sys.argv[sys.argv.index("--") + 1:]
show_material((base[0] + GAP / 2, base[1], base[2] + 0.6), 1.9, (0.74, 0.67, 0.06, 0.06),   # from the front,
              frame=20, solid=solid)                                                    # a little from above
