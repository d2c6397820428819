"""The Reconstruct operator and its worker job: a real run, bad input, cancel at every stage."""
import hashlib
import json
import os
import time

import bpy
import numpy as np
import pytest
from job_report import check_report_doc

import tree_from_video
from tree_from_video.core.job import Job
from tree_from_video.operators import jobs, reconstruct_op

from samples import committed, plain_settings
from trees import addon  # noqa: F401  (autouse fixture: the add-on registered per test)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

VIDEO = os.path.join(committed("broad"), "video.mp4")
OUTLINE = os.path.join(committed("broad"), "outline.json")




def _ids():
    return {a: set(getattr(bpy.data, a).keys()) for a in ("objects", "meshes", "armatures", "actions", "collections")}


def _run_op():
    """Run the operator blocking; background Blender raises reported errors, the wheel returns."""
    try:
        return bpy.ops.tree_video.reconstruct("EXEC_DEFAULT"), ""
    except RuntimeError as exc:
        return {"CANCELLED"}, str(exc)


def test_reconstruct_builds_the_tree(addon):
    addon.video_path, addon.outline_path = VIDEO, OUTLINE
    addon.use_frame_range, addon.frame_start, addon.frame_end = True, 1, 24
    addon.collection_name = "Oak"
    result, err = _run_op()
    assert result == {"FINISHED"}, err
    coll = bpy.data.collections["Oak"]
    rig = next(o for o in coll.objects if o.type == "ARMATURE")
    assert len(rig.data.bones) > 50
    assert bpy.context.scene.frame_end == 24
    # a second run with the same name is refused unless asked, and changes nothing
    before = _ids()
    result, err = _run_op()
    assert result == {"CANCELLED"} and _ids() == before
    addon.replace_existing = True
    assert _run_op()[0] == {"FINISHED"}
    assert len([c for c in bpy.data.collections if c.name.startswith("Oak")]) == 1


def test_an_outline_of_two_trees_builds_two_collections(addon, tmp_path):
    """Issue 31: a file of two polygons (here the broad tree's outline and a box round the fence
    and house beside it, which sway nothing: their tracks stand still) reconstructs both, one
    collection each, ``Oak 1`` and ``Oak 2``; a second run is refused for either name."""
    import json
    poly = json.load(open(OUTLINE))["polygon"]
    path = tmp_path / "two.json"
    path.write_text(json.dumps([poly, [[340, 200], [470, 200], [470, 330], [340, 330]]]))
    addon.video_path, addon.outline_path = VIDEO, str(path)
    addon.use_frame_range, addon.frame_start, addon.frame_end = True, 1, 12
    addon.collection_name = "Oak"
    result, err = _run_op()
    assert result == {"FINISHED"}, err
    rigs = []
    for name in ("Oak 1", "Oak 2"):
        rig = next(o for o in bpy.data.collections[name].objects if o.type == "ARMATURE")
        assert len(rig.data.bones) > 5
        rigs.append(rig)
    assert tuple(rigs[0].location) == (0.0, 0.0, 0.0) and rigs[1].location.x > 2.0    # where the house stands
    assert "Oak" not in bpy.data.collections
    before = _ids()
    assert _run_op()[0] == {"CANCELLED"} and _ids() == before


@pytest.mark.parametrize("case", ["no video", "missing video", "no outline", "outline outside", "empty mask"])
def test_bad_input_is_reported_and_changes_nothing(addon, case, tmp_path):
    addon.video_path, addon.outline_path = VIDEO, OUTLINE
    if case == "no video":
        addon.video_path = ""
    elif case == "missing video":
        addon.video_path = str(tmp_path / "nope.mp4")
    elif case == "no outline":
        addon.outline_path = ""
    elif case == "outline outside":
        p = tmp_path / "far.json"
        p.write_text("[[2000, 2000], [2100, 2000], [2100, 2100]]")
        addon.outline_path = str(p)
    elif case == "empty mask":
        addon.outline_source = "MASK"
        addon.outline_mask = bpy.data.masks.new("empty")
    before = _ids()
    if case == "no video":       # poll refuses: nothing to run
        assert not bpy.ops.tree_video.reconstruct.poll()
        return
    result, err = _run_op()
    assert result == {"CANCELLED"}
    assert _ids() == before


def test_mask_outline_is_converted_to_pixels(addon):
    mask = bpy.data.masks.new("outline")
    spline = mask.layers.new().splines.new()
    pts = [(0.25, 0.1), (0.75, 0.1), (0.75, 0.9), (0.25, 0.9)]
    spline.points.add(len(pts) - 1)
    for p, co in zip(spline.points, pts):
        p.co = co
    poly = reconstruct_op.mask_polygon(mask, 480, 360)
    assert poly == pytest.approx(np.array([[120, 324], [360, 324], [360, 36], [120, 36]]))


@pytest.mark.alone
@pytest.mark.parametrize("stage", ["tracking", "hierarchy", "skeleton", "lift", "motion"])
def test_cancel_at_every_stage_stops_within_a_second(stage):
    s = plain_settings(frames="0:60")
    job = Job(reconstruct_op.make_work(VIDEO, OUTLINE, s, "T")).start()
    t0 = time.monotonic()
    while job.stage != stage and not job.done and time.monotonic() - t0 < 120:
        time.sleep(0.005)
    assert job.stage == stage, f"never reached {stage} (at {job.stage})"
    t_cancel = time.monotonic()
    job.cancel()
    assert job.join(timeout=1.0), f"still running 1 s after cancel in {stage}"
    print(f"{stage}: stopped {1000 * (time.monotonic() - t_cancel):.0f} ms after cancel")
    assert job.cancelled and job.result is None and job.error is None


def test_internal_errors_become_one_line_with_details():
    def boom(progress):
        raise ZeroDivisionError("x")
    job = Job(boom).run_here()
    assert job.error.startswith("internal error (ZeroDivisionError") and "Traceback" in job.details


def test_unregister_stops_running_jobs():
    job = Job(reconstruct_op.make_work(VIDEO, OUTLINE, plain_settings(), "T")).start()
    jobs._RUNNING.add(job)
    time.sleep(0.2)
    jobs.cancel_all(timeout=2.0)
    assert not job.alive and not jobs._RUNNING


def test_preview_keeps_tracks_and_skeleton_for_the_clip_editor(addon):
    from tree_from_video.operators.scene import clip_overlay

    from samples import load_truth
    addon.video_path, addon.outline_path = VIDEO, OUTLINE
    addon.use_frame_range, addon.frame_start, addon.frame_end = True, 11, 40
    before = _ids()
    result = bpy.ops.tree_video.preview("EXEC_DEFAULT")
    assert result == {"FINISHED"} and _ids() == before          # nothing added to the scene
    assert clip_overlay.frame_geometry(VIDEO, 10) is None        # before the range
    assert clip_overlay.frame_geometry("/other.mp4", 11) is None
    pts, seg = clip_overlay.frame_geometry(VIDEO, 11)           # clip frame 11 = video frame 10
    assert len(pts) > 100 and len(seg) % 2 == 0
    assert ((pts >= 0) & (pts <= 1)).all()
    # the skeleton's root (first segment's start is an edge from the root) sits at the true base
    truth = load_truth(committed("broad"))
    base = truth["nodes2d_image"][10, 0] / [480, 360]
    root = clip_overlay.overlay_of(clip_overlay.owners(VIDEO)[0])["nodes"][0, 0] / [480, 360]
    assert np.abs(root - base).max() < 0.03
    # every node with its motion confidence, drawn in the colour of its bin; frame 1 is exact (1.0)
    nodes, conf = clip_overlay.frame_confidence(VIDEO, 21)
    kept = clip_overlay.overlay_of(clip_overlay.owners(VIDEO)[0])
    assert len(nodes) == len(conf) == kept["nodes"].shape[1] and np.all(kept["confidence"][0] == 1.0)
    assert ((conf >= 0) & (conf <= 1)).all() and conf[0] == 1.0 and np.mean(conf >= 0.5) > 0.9   # the base is fixed
    assert clip_overlay.frame_confidence(VIDEO, 10) is None
    # frame 1's foreground outline, on the run's first frame only, around the tree's base
    fg = clip_overlay.frame_foreground(VIDEO, 11)
    assert fg is not None and len(fg) > 50 and len(fg) % 2 == 0 and ((fg >= 0) & (fg <= 1)).all()
    assert clip_overlay.frame_foreground(VIDEO, 12) is None
    assert np.abs(fg - [base[0], 1 - base[1]]).sum(1).min() < 0.05
    # only live tracks are kept (8 bytes each): frame t's are rows track_start[t]..track_start[t + 1]
    assert "tracks" not in kept and kept["track_start"][-1] == len(kept["track_xy"])
    assert kept["track_start"][1] - kept["track_start"][0] == len(pts) and len(kept["track_start"]) == 31
    assert addon.motion_measured == pytest.approx(1 - np.mean(kept["confidence"][1:] < 0.5), abs=1e-6)
    tree_from_video.unregister()
    assert not clip_overlay._decoded                              # cleared with the add-on
    tree_from_video.register()


def test_export_buttons_write_the_tree_and_refuse_bad_targets(addon, tmp_path):
    from tree_from_video.operators.scene import export
    addon.video_path, addon.outline_path = VIDEO, OUTLINE
    addon.use_frame_range, addon.frame_start, addon.frame_end = True, 1, 24
    addon.collection_name = "Export Me"
    assert not bpy.ops.tree_video.export.poll()                      # nothing built yet
    assert _run_op()[0] == {"FINISHED"}
    addon.collection_name = "Next Tree"           # the next Reconstruct's name: not what is exported
    addon.output_dir = str(tmp_path / "exports")
    from tree_from_video.operators import export_op  # the live module (register re-imports it)
    assert [c.name for c in export_op.targets(bpy.context, addon)] == ["Export Me"]   # the new tree
    formats = ["FBX", "GLB"] + (["USD"] if export.has_usd() else [])
    for fmt in formats:
        addon.export_format = fmt
        assert bpy.ops.tree_video.export() == {"FINISHED"}
    names = sorted(f for f in os.listdir(tmp_path / "exports") if os.path.isfile(tmp_path / "exports" / f))
    files = [{"FBX": "Export_Me.fbx", "GLB": "Export_Me.glb", "USD": "Export_Me.usdc"}[f] for f in formats]
    assert names == sorted(files + [f + ".report.json" for f in files])       # each file with the run's report
    doc = json.loads((tmp_path / "exports" / "Export_Me.glb.report.json").read_text())
    check_report_doc(doc)
    assert doc["status"] == "ok" and doc["settings"]["frames"] == "0:24" and doc["video"]["frames"] == [0, 24]
    assert doc["input"]["sha256"] == hashlib.sha256(open(VIDEO, "rb").read()).hexdigest()
    assert doc["counts"]["trees"] == 1 and doc["counts"]["bones"] > 50 and doc["counts"]["tracks"] > 100
    assert {"skeleton", "lift", "motion"} <= set(doc["stages"]) and any(s.startswith("tracking") for s in doc["stages"])
    assert doc["versions"]["blender"] == bpy.app.version_string
    # the panel's report holds a job file's options: the batch reads the same settings from them
    from tree_from_video.core import jobs as core_jobs
    again = core_jobs.from_flat({**doc["settings"], "video": VIDEO, "outline": OUTLINE, "out": str(tmp_path / "again")})
    again.settings.cache_dir = reconstruct_op.cache_dir()
    assert again.settings == reconstruct_op.settings_from(addon)
    fbx = tmp_path / "exports" / "Export_Me.fbx"
    before = fbx.stat().st_mtime_ns
    addon.export_format = "FBX"
    try:                                                              # exists, no overwrite
        result = bpy.ops.tree_video.export()
    except RuntimeError as exc:
        assert str(exc) == f"Error: {fbx} exists (and 1 more): tick Overwrite or choose another name\n"   # its report too
        result = {"CANCELLED"}
    assert result == {"CANCELLED"} and fbx.stat().st_mtime_ns == before
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    addon.output_dir = str(blocker / "sub")                           # unwritable: a file in the way
    try:
        result = bpy.ops.tree_video.export()
    except RuntimeError:
        result = {"CANCELLED"}
    assert result == {"CANCELLED"} and blocker.read_text() == "x"


def test_an_overlay_kept_in_the_dense_format_of_older_files_still_draws():
    """Files saved before kept every track's position every frame, NaN where not live."""
    import io

    from tree_from_video.operators.scene import clip_overlay
    F, P = 3, 4
    tracks = np.full((F, P, 2), np.nan, np.float32)
    tracks[1, 1:3] = [[48.0, 36.0], [96.0, 72.0]]
    buf = io.BytesIO()
    np.savez(buf, size=np.array([480.0, 360.0]), scale=np.float64(1.0), start=np.int64(0), tracks=tracks,
             nodes=np.zeros((F, 2, 2), np.float32), edges=np.array([[0, 1]], np.int32))
    old = os.path.abspath("/tmp/an_old_clip.mp4")
    bpy.context.scene[clip_overlay.KEY] = {"video": old, "made": time.time(), "npz": buf.getvalue()}
    pts, seg = clip_overlay.frame_geometry(old, 2)                    # clip frame 2 = row 1
    assert pts == pytest.approx(np.array([[0.1, 0.9], [0.2, 0.8]]))
    assert len(clip_overlay.frame_geometry(old, 1)[0]) == 0
    del bpy.context.scene[clip_overlay.KEY]
    clip_overlay.clear()


def test_a_photo_reconstructs_a_swaying_tree(addon, tmp_path):
    """Issue 35: a photo as the Source (frame 1 of the broad sample as a JPEG) builds a tree that
    sways as its form's species for 8 s; a photo of one flat colour is refused with one line."""
    import cv2
    cap = cv2.VideoCapture(VIDEO)
    ok, frame = cap.read()
    cap.release()
    photo = str(tmp_path / "oak.jpg")
    assert ok and cv2.imwrite(photo, frame)
    addon.video_path, addon.outline_path, addon.collection_name = photo, OUTLINE, "Photo Oak"
    result, err = _run_op()
    assert result == {"FINISHED"}, err
    rig = next(o for o in bpy.data.collections["Photo Oak"].objects if o.type == "ARMATURE")
    tip = max(rig.pose.bones, key=lambda b: (rig.matrix_world @ b.tail).z)
    tails = []
    for f in (1, 40, 80, 120):
        bpy.context.scene.frame_set(f)
        tails.append(np.array(rig.matrix_world @ tip.tail))
    assert bpy.context.scene.frame_end >= 8 * 24                       # 8 s of sway
    assert addon.motion_measured < 0                                   # nothing measured: the species' sway
    assert np.ptp(np.array(tails), axis=0).max() > 0.01               # it moves (metres)
    # Source › Photo: another species, length and wind, recorded in the run's report
    from tree_from_video.operators.scene import provenance
    addon.photo_species, addon.photo_seconds, addon.photo_wind = "sparse", 3.0, 2.0
    addon.collection_name = "Photo Sparse"
    result, err = _run_op()
    assert result == {"FINISHED"}, err
    coll = bpy.data.collections["Photo Sparse"]
    rig = next(o for o in coll.objects if o.type == "ARMATURE")
    from tree_from_video.operators.scene.action_api import rig_action
    start, end = rig_action(rig).frame_range
    fps = bpy.context.scene.render.fps / bpy.context.scene.render.fps_base
    assert (start, end) == (1, round(3 * fps) + 1)                     # 3 s at the photo's rate, both ends
    doc = provenance.kept(coll)
    assert (doc["settings"]["species"], doc["settings"]["seconds"], doc["settings"]["wind"]) == ("sparse", 3.0, 2.0)
    # Outline › Automatic on a photo: the tree found in it (nothing sways to find it by)
    addon.outline_source, addon.collection_name = "AUTO", "Photo Auto"
    result, err = _run_op()
    assert result == {"FINISHED"}, err
    rig = next(o for o in bpy.data.collections["Photo Auto"].objects if o.type == "ARMATURE")
    assert len(rig.data.bones) > 50
    addon.outline_source = "FILE"
    flat = str(tmp_path / "flat.png")
    cv2.imwrite(flat, np.full((300, 400, 3), 90, np.uint8))
    addon.video_path, addon.collection_name = flat, "Flat"
    result, err = _run_op()
    assert result == {"CANCELLED"} and "Flat" not in bpy.data.collections


def test_a_bark_image_makes_the_bark(addon, tmp_path):
    """Issue 36: *Bark Image* (a synthetic close-up with moss) makes the reconstructed tree's bark a
    material of three packed images (colour, normal, roughness) whose colour is the photo's tile;
    a missing bark image is refused with one line and nothing built."""
    import cv2
    from bark_photos import bark_photo

    from tree_from_video.operators.scene import materials
    photo, _, _ = bark_photo(5)
    path = tmp_path / "bark.jpg"
    cv2.imwrite(str(path), photo)
    addon.video_path, addon.outline_path, addon.collection_name = VIDEO, OUTLINE, "Mossy"
    addon.use_frame_range, addon.frame_start, addon.frame_end = True, 1, 12
    addon.bark_image, addon.bark_moss = str(path), 0.0
    result, err = _run_op()
    assert result == {"FINISHED"}, err
    mesh = next(o for o in bpy.data.collections["Mossy"].objects if o.name.endswith("Branches"))
    mat = mesh.data.materials[0]
    assert mat.name.endswith("Bark") and materials.BARK_PHOTO_KEY in mat
    images = {n.image.colorspace_settings.name for n in mat.node_tree.nodes if n.type == "TEX_IMAGE"}
    assert len([n for n in mat.node_tree.nodes if n.type == "TEX_IMAGE"]) == 3 and images == {"sRGB", "Non-Color"}
    albedo = next(n.image for n in mat.node_tree.nodes if n.type == "TEX_IMAGE" and n.image.colorspace_settings.name == "sRGB")
    px = np.empty(albedo.size[0] * albedo.size[1] * 4, np.float32)
    albedo.pixels.foreach_get(px)
    rgb = px.reshape(-1, 4)[:, :3].mean(0) * 255
    hsv = cv2.cvtColor(np.uint8([[rgb[::-1]]]), cv2.COLOR_BGR2HSV)[0, 0]
    print(f"\nthe bark's colour {rgb.round(1)} (hue {hsv[0]}), from the photo's brown bark; Moss 0")
    assert hsv[0] < 30                                                    # brown, not moss green
    addon.bark_image, addon.collection_name, addon.replace_existing = str(tmp_path / "none.jpg"), "Other", False
    result, err = _run_op()
    assert result == {"CANCELLED"} and "Other" not in bpy.data.collections
