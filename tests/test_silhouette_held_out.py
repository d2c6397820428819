"""Issue 19's silhouette bar on every wind and look variant, on seed 2 (held out): a Workbench
render of frame 1 (:func:`silhouette.render_silhouette`) overlaps the true tree mask with
IoU ≥ 0.7. On the bpy wheel only: the H.264 variants need ffmpeg, which the real-Blender chroot
of the bpy 5.3 leg does not have (the first sample set's silhouettes run there too,
tests/test_silhouette.py)."""
import bpy
import pytest
import report
from silhouette import render_silhouette, true_mask

from tree_from_video.core import pipeline
from tree_from_video.operators.scene import build
from tree_from_video.sample_videos import synth_tree

from trees import empty_scene  # noqa: F401  (autouse fixture)

pytestmark = pytest.mark.slow


#: issue 19's bar for every variant but the nearly leafless ``sparse``
BAR = 0.7
HELD_OUT = 2
NEW_VARIANTS = synth_tree.WIND_VARIANTS + synth_tree.LOOK_VARIANTS
#: variant -> (IoU measured when recorded, floor the test holds it to) where the bar is not met yet
GAPS: dict[str, tuple[float, float]] = {}


@pytest.fixture(scope="module")
def held_out(tmp_path_factory):
    """{variant: Result} of seed 2 (held out) of every wind and look variant, 48 frames (frame 1's
    tree is the clip's whatever its length), the first 24 reconstructed."""
    from samples import generate, video_path
    out = {}
    for v in NEW_VARIANTS:
        assert HELD_OUT in synth_tree.SEEDS[v]["held_out"]
        folder = generate(v, str(tmp_path_factory.mktemp(v)), seed=HELD_OUT, frames=48)
        out[v] = pipeline.run(video_path(folder), f"{folder}/outline.json", pipeline.Settings(frames="0:24"))
    return out


@pytest.mark.parametrize("variant", NEW_VARIANTS)
def test_held_out_silhouettes_cover_the_video_tree(held_out, variant, tmp_path):
    """IoU ≥ 0.7 against the true mask of frame 1 on seed 2 of every wind and look variant (the
    backlit one: a dark crown with no inner corners against an overcast sky, shadowed ground)."""
    res = held_out[variant]
    assert res.skeleton.hidden_trunk == (variant == "hidden")    # only a crown on the ground hides its trunk
    assert res.form == ("conifer" if variant in ("conifer_storm", "tiny") else "broadleaf"), res.form_why
    tree = pipeline.build_3d(res, pipeline.Settings(), name="Sil")
    build.build_tree(bpy.context, tree, "Sil")
    sil = render_silhouette(tree, str(tmp_path / "sil.png"))
    truth = true_mask(variant, HELD_OUT, 48)
    iou = (sil & truth).sum() / max((sil | truth).sum(), 1)
    report.add("frame-1 silhouette, held-out seed 2 (tests/test_silhouette.py)",
               [f"{variant}: IoU {iou:.3f}, covered {(sil & truth).sum() / truth.sum():.3f}, "
                f"outside {(sil & ~truth).sum() / truth.sum():.3f}, {tree.leaves.count if tree.leaves else 0} clusters"])
    gap = GAPS.get(variant)
    if gap is None:
        assert iou >= BAR
    else:
        assert iou < BAR + (BAR - gap[1]) / 4, f"{variant} now meets the bar ({iou:.3f}): delete GAPS[{variant!r}]"
        assert iou >= gap[1], f"{variant}: {iou:.3f} fell below the recorded floor {gap[1]} (was {gap[0]})"
