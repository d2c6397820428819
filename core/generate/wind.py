"""Wind controls for generated motion: a strength factor and an audio-driven gust envelope.

The synthesized rotation of every node (radians, :mod:`.sway`) is multiplied per frame by

    g(t) = wind · a(t)

where ``wind`` scales the amplitudes of the dominant frequencies (1 = as in the example tree,
2 = twice the sway) and ``a(t)`` is the amplitude envelope of an audio file (mean 1 over the
clip; 1 everywhere without audio): a windy-day recording makes the trees sway harder in the
gusts. Rotations are small, so doubling ``wind`` doubles the node displacements to first order.
"""
from __future__ import annotations

import os
import warnings

import numpy as np

from ..errors import InputError

SMOOTH_S = 0.25          # Gaussian smoothing of the audio RMS (seconds): gusts, not syllables


def read_wav(path: str | os.PathLike) -> tuple[int, np.ndarray]:
    """``(rate, samples (S,))`` float64 in [−1, 1] (channels averaged) from a WAV file.

    int16 / int32 are divided by their full scale, uint8 is centred on 128, float data is kept.
    :class:`InputError` for a missing, non-WAV, unreadable or empty file."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"audio file '{path}' does not exist; give a .wav recording (e.g. wind)")
    from scipy.io import wavfile
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")           # WavFileWarning on odd chunks
            rate, data = wavfile.read(path)
    except (ValueError, OSError, EOFError, IndexError) as exc:
        raise InputError(f"audio file '{path}' is not a readable WAV ({exc.__class__.__name__}); "
                         "convert it to PCM .wav (16-bit, 32-bit or float)") from None
    data = np.asarray(data)
    if data.size == 0 or rate <= 0:
        raise InputError(f"audio file '{path}' holds no samples; give a recording at least a second long")
    if data.dtype == np.uint8:
        x = (data.astype(np.float64) - 128.0) / 128.0
    elif np.issubdtype(data.dtype, np.integer):
        x = data.astype(np.float64) / float(np.iinfo(data.dtype).max + 1)
    else:
        x = data.astype(np.float64)
    if x.ndim == 2:
        x = x.mean(axis=1)
    x = np.where(np.isfinite(x), x, 0.0)
    return int(rate), x


def envelope_of_samples(x: np.ndarray, rate: float, fps: float, n_frames: int,
                        smooth_s: float = SMOOTH_S) -> np.ndarray:
    """``(F,)`` amplitude envelope, mean 1: the RMS of ``x`` over each frame's window
    ``[f/fps, (f+1)/fps)`` (a clip shorter than the animation is looped), smoothed by a Gaussian
    of ``smooth_s`` seconds, divided by its mean."""
    x = np.asarray(x, np.float64)
    if n_frames <= 0:
        return np.ones(0)
    dur = n_frames / fps
    need = int(np.ceil(dur * rate)) + 1
    if len(x) < need:
        x = np.tile(x, int(np.ceil(need / len(x))))
    c = np.concatenate([[0.0], np.cumsum(x * x)])
    edges = np.round(np.arange(n_frames + 1) * rate / fps).astype(np.int64)
    edges = np.clip(edges, 0, len(x))
    cnt = np.maximum(np.diff(edges), 1)
    rms = np.sqrt(np.maximum((c[edges[1:]] - c[edges[:-1]]) / cnt, 0.0))
    sig = smooth_s * fps
    if sig > 0.5 and n_frames > 1:
        r = int(np.ceil(3 * sig))
        k = np.exp(-0.5 * (np.arange(-r, r + 1) / sig) ** 2)
        pad = np.pad(rms, r, mode="reflect") if n_frames > r else np.pad(rms, r, mode="edge")
        rms = np.convolve(pad, k / k.sum(), mode="valid")
    m = float(rms.mean())
    if not m > 1e-9:
        raise InputError("the audio is silent over the animation; give a recording with audible wind")
    return rms / m


def audio_envelope(path: str | os.PathLike, fps: float, n_frames: int, smooth_s: float = SMOOTH_S) -> np.ndarray:
    """``(n_frames,)`` amplitude envelope of a WAV file at the scene's ``fps``, mean 1
    (:func:`envelope_of_samples`). :class:`InputError` for unreadable / non-WAV / empty / silent
    files."""
    if not fps > 0:
        raise InputError(f"frame rate {fps} is not positive")
    rate, x = read_wav(path)
    try:
        return envelope_of_samples(x, rate, fps, n_frames, smooth_s)
    except InputError as exc:
        raise InputError(f"audio file '{os.fspath(path)}': {exc}") from None


def gain_curve(n_frames: int, wind: float = 1.0, audio: np.ndarray | None = None) -> np.ndarray:
    """``(F,)`` per-frame factor ``g(t) = wind · a(t)`` on the synthesized rotations; ``audio``
    an envelope from :func:`audio_envelope` (resized by linear interpolation if its length
    differs)."""
    if not np.isfinite(wind) or wind < 0:
        raise InputError(f"wind strength {wind} must be a number ≥ 0 (1 = as in the example)")
    g = np.full(n_frames, float(wind))
    if audio is not None:
        a = np.asarray(audio, np.float64).ravel()
        if len(a) == 0:
            raise InputError("the audio envelope is empty; give a recording at least a second long")
        if len(a) != n_frames:
            a = np.interp(np.linspace(0, len(a) - 1, n_frames), np.arange(len(a)), a)
        g *= a
    return g
