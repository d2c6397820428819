"""The reconstructed tree looks like the one in the video: a Workbench render of frame 1 (orthographic
front view, the video's framing) overlaps the true tree mask (branches + leaves of the synthetic
frame) with IoU ≥ the bar below, on every generated sample."""

import bpy
import pytest
import report
from silhouette import render_silhouette, true_mask

from tree_from_video.core import pipeline
from tree_from_video.operators.scene import build

from trees import empty_scene  # noqa: F401  (autouse fixture)

pytestmark = [pytest.mark.bpy53, pytest.mark.slow]

#: measured (traced skeleton, the default look: twigs 2, curliness 0.3, rough bark, leaves, branch
#: widths and centre lines fitted to frame 1 and tapered, the trace also on frame 1's own pixels,
#: clusters on their tufts' centres, and since issue 19 clusters added where the cards left frame
#: 1's foliage bare, a graph-cut foreground for a crown the colour test misses): broad 0.770,
#: grey 0.780, gentle 0.763, hard 0.738, conifer 0.731, dense 0.837, sparse 0.636 (0.530 bare);
#: before the top-up: broad 0.771, grey 0.779, gentle 0.764, hard 0.750, conifer 0.712, dense
#: 0.851, sparse 0.628. Issue 19's bar is 0.7 (the nearly leafless sparse: 0.6); the bars keep
#: what each variant reaches above it.
BARS = {"broad": 0.75, "hard": 0.71, "dense": 0.82, "conifer": 0.7, "gentle": 0.74, "grey": 0.76, "sparse": 0.6}


@pytest.mark.parametrize("variant", sorted(BARS))
def test_rendered_silhouette_overlaps_the_video_tree(runs, variant, tmp_path):
    res = runs[variant]["traced"]
    assert not res.skeleton.hidden_trunk                       # every one stands on a visible trunk
    assert res.form == ("conifer" if variant == "conifer" else "broadleaf"), res.form_why
    s = pipeline.Settings()          # the product's defaults: twigs 2, curliness 0.3, rough bark
    tree = pipeline.build_3d(res, s, name="Sil")
    built = build.build_tree(bpy.context, tree, "Sil")
    sil = render_silhouette(tree, str(tmp_path / "sil.png"))
    truth = true_mask(variant)
    assert sil.shape == truth.shape
    iou = (sil & truth).sum() / max((sil | truth).sum(), 1)
    assert built["leaves"] is not None
    built["leaves"].hide_render = True
    bare = render_silhouette(tree, str(tmp_path / "bare.png"))
    iou_bare = (bare & truth).sum() / max((bare | truth).sum(), 1)
    report.add("frame-1 silhouette vs the true tree mask (tests/test_silhouette.py)",
               [f"{variant}: silhouette IoU {iou:.3f} (branches only {iou_bare:.3f}); "
                f"{tree.leaves.count if tree.leaves else 0} leaf clusters, rendered {sil.sum()} px vs true "
                f"{truth.sum()} px"])
    assert iou >= BARS[variant]
    assert iou > iou_bare                      # the leaves go where the video has foliage

