"""A tree from one photo (issue 35, seed 003): the photo is a one-frame video to the 2D stages (the
skeleton traced on it, the frame-1 evidence, foreground, trunk and form work as for a video) and the
lift takes its depth from the learned network; what a photo cannot give, the motion, comes from a
species: its sway (paper §5.2, :mod:`.sway`) sampled for the traced tree's own skeleton and
put on its rest pose by forward kinematics, so the photo's tree sways like its species.

:func:`check_photo` turns what cannot be a tree photo into one line (:class:`InputError`): a file
that is no image, an animated GIF, a picture under :data:`MIN_SIDE` px on its shorter side, a picture
of one flat colour.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import InputError
from ..params import param

#: files read as a photo (a one-frame video) rather than a video
PHOTO_EXTENSIONS = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".webp", ".bmp", ".gif")
#: the shorter side a photo needs, px (the trace needs the tree at least ~100 px tall)
MIN_SIDE = 128
#: below this standard deviation of the grey levels the picture is one flat colour
FLAT_STD = 2.0
#: the species that sways a photo's tree of each form when none is given (the shipped library)
SPECIES_OF_FORM = {"broadleaf": "broad", "conifer": "conifer", "palm": "palm"}


@dataclass
class PhotoMotion:
    """How a photo's tree sways: ``species`` (a library name or a species .json; "": the library's
    species of the traced form), ``seconds`` of animation, ``wind`` (1 as in the species' source
    clip, 2 twice as strong), ``seed`` of the sampled sway, ``rise_s`` seconds over which the wind
    rises from calm (a smoothstep), so that frame 1 is the photo's own pose."""

    species: str = ""
    seconds: float = param(8.0, 0.0, 600.0, lo_open=True, what="--seconds", unit="s")
    wind: float = param(1.0, 0.0, 10.0, what="--wind")
    seed: int = 0
    rise_s: float = param(1.0, 0.0, 60.0, what="the wind's rise", unit="s")


def is_photo(path: str | os.PathLike) -> bool:
    """Whether ``path`` is read as a photo (by its extension, :data:`PHOTO_EXTENSIONS`)."""
    return os.path.splitext(os.fspath(path))[1].lower() in PHOTO_EXTENSIONS


def check_photo(path: str | os.PathLike) -> np.ndarray:
    """The photo ``path`` (BGR uint8), or :class:`InputError` naming why it cannot be one."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"photo '{path}' does not exist; check the path")
    if path.lower().endswith(".gif"):
        cap = cv2.VideoCapture(path)
        try:
            frames = 0
            while frames < 2 and cap.read()[0]:
                frames += 1
        finally:
            cap.release()
        if frames > 1:
            raise InputError(f"'{path}' is an animated GIF; give one frame as a photo (e.g. ffmpeg -i IN.gif "
                             "-frames:v 1 OUT.png), or the clip as a video (ffmpeg -i IN.gif OUT.mp4)")
    img = cv2.imread(path, cv2.IMREAD_COLOR)
    if img is None:
        raise InputError(f"'{path}' cannot be read as an image; give a JPEG, PNG, TIFF or WebP photo of the tree")
    h, w = img.shape[:2]
    if min(h, w) < MIN_SIDE:
        raise InputError(f"photo '{path}' is {w}×{h} px; a photo needs at least {MIN_SIDE} px on its shorter side")
    if float(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).std()) < FLAT_STD:
        raise InputError(f"photo '{path}' is one flat colour; give a photo that shows the tree")
    return img


def species_for(m: PhotoMotion, form: str):
    """The species model that sways a tree of ``form``: ``m.species`` or the form's library species."""
    from .batch import load_species_spec
    return load_species_spec(m.species or SPECIES_OF_FORM.get(form, "broad"))[0]


def sway(model, parents: np.ndarray, rest: np.ndarray, m: PhotoMotion, fps: float) -> np.ndarray:
    """``(F, N, 3)`` node positions (the units of ``rest (N, 3)``): the species' sway sampled for
    this skeleton (:func:`.generate.sway.sample_rotations`, ``F = round(seconds · fps) + 1``), scaled
    by the wind and by its rise (0 at frame 1, smoothstep to 1 at ``rise_s``: the sway's random
    phases would otherwise start the tree away from the photo), on the rest pose by forward
    kinematics (bone lengths exact, the root still)."""
    from .sway import forward_kinematics, sample_rotations
    n = int(round(m.seconds * fps)) + 1
    rng = np.random.default_rng(m.seed)
    rot = sample_rotations(model, parents, np.asarray(rest, np.float64), n, fps, rng) * float(m.wind)
    return forward_kinematics(parents, rest, rot * wind_rise(n, fps, m.rise_s)[:, None, None])


def wind_rise(n: int, fps: float, rise_s: float) -> np.ndarray:
    """``(n,)`` the wind's share at each frame: ``3u² − 2u³`` with ``u = min(t / rise_s, 1)``, ``t``
    seconds from frame 1 (all ones when ``rise_s`` is 0)."""
    t = np.arange(n) / float(fps)
    u = np.clip(t / rise_s, 0.0, 1.0) if rise_s > 0 else np.ones(n)
    return u * u * (3.0 - 2.0 * u)
