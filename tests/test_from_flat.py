"""One reader of flat options (core.pipeline.from_flat, issue 34): the batch's options, the
panel's properties and the API's keywords become the same Settings through it; hand cases for the
nested names and the switches; unknown names refused."""
import dataclasses

import pytest

from tree_from_video import api, cli
from tree_from_video.core import pipeline
from tree_from_video.core.detail.twigs import TwigParams
from tree_from_video.core.errors import InputError

from trees import addon  # noqa: F401  (autouse fixture: the add-on registered per test)


def _plain(s: pipeline.Settings) -> dict:
    """The settings as a flat dict, floats to 6 significant digits (the panel's properties are
    single precision)."""
    out = {}

    def walk(prefix, value):
        if isinstance(value, dict):
            for k, v in value.items():
                walk(f"{prefix}.{k}" if prefix else k, v)
        else:
            out[prefix] = float(f"{value:.6g}") if isinstance(value, float) else value
    d = dataclasses.asdict(s)
    d.pop("cache_dir", None)
    walk("", d)
    return out


def test_hand_cases():
    s = pipeline.from_flat({"twigs": 3, "solver": "deterministic", "leaf_density": 0.5, "candidates": 9,
                            "max_leaf_clusters": 300, "levels": 5, "conifer": True})
    assert s.twigs.depth == 3 and s.motion.solver == "deterministic" and s.leaves.density == 0.5
    assert s.lift.candidates == 9 and s.leaves.max_clusters == 300 and s.levels == 5 and s.form == "conifer"
    assert pipeline.from_flat({"conifer": True, "form": "palm"}).form == "palm"        # a form given wins
    bare = pipeline.from_flat({"leaves": False, "leaf_density": 0.5})
    assert bare.leaves is None                                                      # leaf options moot
    assert pipeline.from_flat({"twigs": TwigParams(depth=4)}).twigs.depth == 4
    assert _plain(pipeline.from_flat({})) == _plain(pipeline.Settings())
    with pytest.raises(InputError, match="unknown setting 'colour'"):
        pipeline.from_flat({"colour": "red"})


def test_batch_panel_and_api_agree(addon):
    from tree_from_video.operators import reconstruct_op
    args = cli.build_parser().parse_args(["v.mp4", "--outline", "o.json", "--out", "x", "--levels", "5", "--twigs",
                                          "1", "--leaf-density", "0.5", "--bark", "smooth", "--frames", "0:24"])
    by_batch = cli.settings_from_args(args)
    by_api = api.settings(levels=5, twigs=1, leaf_density=0.5, bark="smooth", frames="0:24")
    addon.levels, addon.twig_depth, addon.leaf_density, addon.bark = 5, 1, 0.5, "smooth"
    addon.use_frame_range, addon.frame_start, addon.frame_end = True, 1, 24
    by_panel = reconstruct_op.settings_from(addon)
    assert _plain(by_batch) == _plain(by_api) == _plain(by_panel)
