"""One source of defaults and ranges: the core's parameter dataclasses (core/params.py). The panel's
properties (ui/properties.py, ``CORE_FIELDS``) take theirs from there; this checks the registered
properties against the core field by field.

:func:`test_panel_properties_match_the_core` is the panel side."""
import pytest

from tree_from_video.core.params import spec
from tree_from_video.ui.properties import CORE_FIELDS
from tree_from_video.ui.ranges import ranged

from trees import addon  # noqa: F401  (autouse fixture: the add-on registered per test)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

#: float properties are stored as float32
F32 = 1e-6


def _panel(props, name):
    return props.bl_rna.properties[name]


@pytest.mark.parametrize("name", sorted(CORE_FIELDS))
def test_panel_properties_match_the_core(addon, name):
    """Default = the core's; enum items = the core's choices (and "custom" where the core also takes a
    pattern such as ``#RRGGBB``, written by the panel from its own colour field); limits: the closed bounds are the
    core's, an open lower bound becomes a small value inside the range, an unbounded side keeps
    Blender's limit; soft limits lie inside the core's range; a new scene starts at the default."""
    cls, field = CORE_FIELDS[name]
    s = spec(cls, field)
    p = _panel(addon, name)
    where = f"panel '{name}' vs {cls.__name__}.{field} ({s.describe()})"
    if s.choices:
        assert p.type == "ENUM", where
        assert tuple(p.enum_items.keys()) == s.choices + (("custom",) if s.pattern else ()), where
        assert p.default == s.default, where
        assert getattr(addon, name) == s.default, where
        return
    assert p.type in ("INT", "FLOAT"), where
    assert p.default == pytest.approx(s.default, rel=F32), where
    assert getattr(addon, name) == pytest.approx(s.default, rel=F32), where
    if s.lo is None:
        assert p.hard_min < -1e9, where
    elif s.lo_open:
        assert s.ok(p.hard_min) and p.hard_min <= 0.1 * max(1.0, s.default), where
    else:
        assert p.hard_min == pytest.approx(s.lo, abs=F32), where
    if s.hi is None:
        assert p.hard_max > 1e9, where
    else:
        assert p.hard_max == pytest.approx(s.hi, rel=F32), where
    for soft in (p.soft_min, p.soft_max):
        assert p.hard_min <= soft <= p.hard_max, where
    assert p.soft_min <= s.default <= p.soft_max, where


def test_every_panel_setting_of_a_ranged_core_field_is_in_the_table(addon):
    """The panel settings that mirror a ranged core field are all in ``CORE_FIELDS`` (none keeps a
    default or range of its own), each pointing at a real field."""
    expected = {"scale", "levels", "skeleton_kind", "fold_alpha", "solver", "height_m", "twig_depth", "curliness",
                "bark", "leaf_density", "leaf_cards", "max_leaf_clusters", "flutter_hz", "flutter_gain"}
    assert expected <= set(CORE_FIELDS)
    for name, (cls, field) in CORE_FIELDS.items():
        spec(cls, field)                                  # raises for a field without a range
        assert name in addon.bl_rna.properties, name


def test_ranged_needs_a_value_inside_an_open_bound():
    from tree_from_video.core.detail.leaf_clusters import LeafParams
    from tree_from_video.core.reconstruct.run import ReconstructSettings
    assert ranged(ReconstructSettings, "levels") == {"default": 6, "min": 2, "max": 9}
    assert ranged(LeafParams, "density", open_min=0.01, soft_min=0.02) == {"default": 1.0, "min": 0.01, "max": 1.0,
                                                                          "soft_min": 0.02}
    assert ranged(LeafParams, "flutter_hz", soft_max=12) == {"default": 2.0, "min": 0.0, "soft_max": 12}
    with pytest.raises(ValueError, match="open_min"):
        ranged(LeafParams, "density")                     # > 0: the caller picks the smallest value
    with pytest.raises(ValueError, match="open_min"):
        ranged(LeafParams, "density", open_min=0.0)
    with pytest.raises(ValueError, match="drop open_min"):
        ranged(ReconstructSettings, "levels", open_min=1)
    with pytest.raises(ValueError, match="outside the core's range"):
        ranged(ReconstructSettings, "levels", soft_max=12)


# ----------------------------------------------------------------------------- the batch options

#: batch option (argparse dest) → (core dataclass, field); the generation options too
CLI_FIELDS = {
    "levels": ("ReconstructSettings", "levels"), "skeleton": ("ReconstructSettings", "skeleton"),
    "scale": ("ReconstructSettings", "scale"), "solver": ("MotionParams", "solver"),
    "height": ("Settings", "height_m"), "twigs": ("TwigParams", "depth"), "curliness": ("MeshParams", "curliness"),
    "bark": ("MeshParams", "bark"), "leaf_density": ("LeafParams", "density"), "leaf_cards": ("LeafParams", "cards"),
    "flutter_hz": ("LeafParams", "flutter_hz"), "wind": ("GenerateRequest", "wind"), "seed": ("GenerateRequest", "seed"),
    "nodes": ("GenerateRequest", "nodes"),
}


def _core_classes():
    from tree_from_video.core.detail.branch_mesh import MeshParams
    from tree_from_video.core.detail.leaf_clusters import LeafParams
    from tree_from_video.core.detail.twigs import TwigParams
    from tree_from_video.core.generate.batch import GenerateRequest
    from tree_from_video.core.pipeline import Settings
    from tree_from_video.core.reconstruct.motion import MotionParams
    from tree_from_video.core.reconstruct.run import ReconstructSettings
    return {c.__name__: c for c in (MeshParams, LeafParams, TwigParams, GenerateRequest, Settings, MotionParams,
                                     ReconstructSettings)}


@pytest.mark.parametrize("dest", sorted(CLI_FIELDS))
def test_batch_options_match_the_core(dest):
    """Each option's default is the core's; an enum option offers exactly the core's choices; a
    ranged option's help names the core's range."""
    from tree_from_video import cli
    classes = _core_classes()
    cls_name, field = CLI_FIELDS[dest]
    s = spec(classes[cls_name], field)
    action = next(a for a in cli.build_parser()._actions if a.dest == dest)
    assert action.default == s.default, (dest, action.default, s.default)
    if s.choices:
        assert tuple(action.choices) == s.choices
    elif s.lo is not None and s.hi is not None:
        assert s.describe() in action.help % {"default": action.default}, action.help


def test_panel_cli_and_core_agree_on_every_shared_setting():
    """The settings the panel and the batch options share start at one default: the core's."""
    from tree_from_video import cli
    classes = _core_classes()
    by_field = {(cls.__name__, f): name for name, (cls, f) in CORE_FIELDS.items()}
    args = cli.build_parser().parse_args(["v.mp4", "--outline", "o.json", "--out", "x"])
    settings = cli.settings_from_args(args)
    from tree_from_video.core import pipeline
    core = pipeline.Settings()
    shared = 0
    for dest, (cls_name, field) in CLI_FIELDS.items():
        panel = by_field.get((cls_name, field))
        if panel is None:
            continue
        shared += 1
        s = spec(classes[cls_name], field)
        assert getattr(args, dest) == s.default, dest
    assert shared >= 10
    # the settings a batch run builds by default are the core's defaults
    assert (settings.levels, settings.twigs.depth, settings.curliness, settings.bark, settings.height_m) == \
        (core.levels, core.twigs.depth, core.curliness, core.bark, core.height_m)
    assert settings.leaves == core.leaves and settings.motion == core.motion and settings.lift == core.lift


def test_the_panels_custom_leaf_colour_is_a_colour_the_core_takes():
    from tree_from_video.core.detail.leaf_clusters import LeafParams
    from tree_from_video.operators.reconstruct_op import leaf_colour_setting
    assert leaf_colour_setting("custom", (0.8, 0.2, 0.0)) == "#CC3300"
    assert leaf_colour_setting("custom", (1.2, -0.1, 0.5)) == "#FF0080"      # clipped to 0..1
    assert leaf_colour_setting("video", (0.8, 0.2, 0.0)) == "video"
    assert spec(LeafParams, "colour").ok(leaf_colour_setting("custom", (0.33, 0.46, 0.18)))


def test_a_generated_tree_has_the_one_look_and_height(addon):
    """Issue 33: api.generate's trees were built with straight tubes and no bark (the grown tree
    carried no look) and the panel grew 8 m trees where the CLI and API grew 10 m ones. A grown tree
    records the branch mesh's look with the core's defaults, and every front end's height is the
    core's."""
    import inspect

    from tree_from_video import api, cli
    from tree_from_video.core.detail.branch_mesh import MeshParams
    from tree_from_video.core.generate.batch import GenerateRequest
    from tree_from_video.operators.scene.branch_mesh import mesh_params
    tree, = api.generate("broad", node_budget=40, n_frames=8)
    look = mesh_params(tree)
    assert (look.curliness, look.bark) == (MeshParams().curliness, MeshParams().bark) == (0.3, "rough")
    height = float(tree.nodes3d[0][:, 2].max() - tree.nodes3d[0][:, 2].min())
    assert 8.5 < height <= 10.5          # grown into a 10 m envelope (it stops short of its top), not 8 m
    assert addon.gen_height == GenerateRequest().height_m == 10.0
    assert inspect.signature(api.generate).parameters["height_m"].default is None   # None: the core's
    args = cli.build_parser().parse_args(["v.mp4", "--out", "d", "--generate", "2"])
    assert args.height == GenerateRequest().height_m
