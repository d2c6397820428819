"""Rendering a built tree's frame-1 silhouette as the video frames it (the silhouette tests)."""
import math

import bpy
import cv2
import numpy as np

from tree_from_video.sample_videos import synth_tree

from groundtruth import true_labels


def render_silhouette(tree, path: str) -> np.ndarray:
    """``(H, W)`` bool: where the built tree covers frame 1 seen like the video (orthographic,
    ``meta["metres_per_px"]`` and ``meta["base_px"]`` place it on the frame)."""
    scene = bpy.context.scene
    W, H = tree.meta["video_size"]
    m = tree.meta["metres_per_px"]
    bx, by = tree.meta["base_px"]
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = max(W, H) * m
    cam.data.clip_end = 1000.0
    cam.location = ((W / 2 - bx) * m, -100.0, (by - H / 2) * m)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    r = scene.render
    r.engine = "BLENDER_WORKBENCH"
    r.film_transparent = True
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.image_settings.file_format = "PNG"
    r.image_settings.color_mode = "RGBA"
    scene.display.shading.light = "FLAT"
    scene.display.shading.color_type = "TEXTURE"       # leaf cards cut out by their alpha
    scene.frame_set(1)
    r.filepath = path
    bpy.ops.render.render(write_still=True)
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    return img[..., 3] > 127


def true_mask(variant: str, seed: int | None = None, frames: int | None = None,
              width: int | None = None, height: int | None = None) -> np.ndarray:
    """``(H, W)`` bool: the true tree (branches and leaves) in frame 1 of a sample variant."""
    lab = true_labels(variant, seed, frames, width, height)
    return (lab == synth_tree.LABEL_BRANCH) | (lab == synth_tree.LABEL_LEAF)
