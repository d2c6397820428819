"""GUI set-up for a screenshot of a forest whose trees each grow in their own crown (issue 36:
*Crown Variety* 0.7, seed 000's contour space) with *Holton Angles* on, the Generate panel beside it:
tests/gui/generate_shot.py's forest with those settings.

    real-blender gui-shot docs/crown_variety.png --size 1600x1000 -- blender --factory-startup \
        --python tests/gui/variety_shot.py
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))   # this folder: generate_shot.py
from generate_shot import forest_shot  # noqa: E402

forest_shot(forest_variants=0,                  # every tree its own crown
            gen_envelope_variation=0.7, gen_allometry=True)
