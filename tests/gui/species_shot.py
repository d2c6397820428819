"""GUI set-up for docs/species.png: the tree reconstructed from sample_videos/broad (left) beside
three trees grown from its species in its own envelope, with as many branch nodes as it has and
twigs as deep (issue 19: generated trees look like their species — crowns as full, trunks as
thick, the same leaf colour).

    real-blender gui-shot docs/species.png --size 1600x900 --wait 12 -- \
        blender --factory-startup --python tests/gui/species_shot.py
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: _addon.py
from _addon import ROOT, open_tree_tab, register_with_sample  # noqa: E402

register_with_sample()
for ob in list(bpy.data.objects):
    bpy.data.objects.remove(ob)

from tree_from_video.core import pipeline  # noqa: E402
from tree_from_video.core.detail.twigs import without_twigs  # noqa: E402
from tree_from_video.core.envelope import envelope_from_meta  # noqa: E402
from tree_from_video.core.generate import growth, species  # noqa: E402
from tree_from_video.operators.scene import build  # noqa: E402

folder = os.path.join(ROOT, "sample_videos", "broad")
s = pipeline.Settings(frames="0:96")
tree = pipeline.build_3d(pipeline.run(os.path.join(folder, "video.mp4"), os.path.join(folder, "outline.json"), s), s,
                         name="Reconstructed")
model = species.fit_species(tree, "broad")
env = envelope_from_meta(tree.meta)
# as many branch nodes as the reconstruction, and the same twigs (the default depth) on top
branches = without_twigs(tree).n_nodes
trees = [tree] + [growth.grow_tree(model, env, growth.GrowParams(seed=seed, n_frames=96, node_budget=branches,
                                                                 name=f"Generated {seed}"))
                  for seed in (1, 2, 3)]
spacing = 1.15 * 2 * max(float(env.radius.max()), 1.0)
for k, t in enumerate(trees):
    built = build.build_tree(bpy.context, t, t.name)
    for ob in bpy.data.collections[t.name].objects:
        if ob.parent is None:
            ob.location.x += k * spacing
    print(t.name, t.n_nodes, "nodes,", t.leaves.count if t.leaves else 0, "leaf clusters", flush=True)


def species_view(space, r3d):
    space.show_region_ui = False
    space.shading.color_type = "TEXTURE"
    r3d.view_perspective = "PERSP"
    r3d.view_rotation = (0.72, 0.69, 0.0, 0.0)          # from the front, a little above
    r3d.view_location = (1.5 * spacing, 0.0, 0.45 * float(env.z.max()))
    r3d.view_distance = 3.3 * spacing


bpy.app.timers.register(open_tree_tab(species_view), first_interval=1.0)
