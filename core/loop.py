"""Seamless loops (issue 33): a tree's motion cut to a loop an engine can repeat without a pop.

A measured motion never repeats, so a loop of ``L`` frames is made from a window of the clip and
the ``D`` frames after it (``D`` = :data:`BLEND_S` seconds, at most a quarter of the loop): over
the loop's first ``D`` frames each bone's rotation is blended, in rotation space, from where the
motion went on after the window's end into the window's own start,

    q_loop(t) = q(a + L + t) ⊗ exp(w(t) · log(q(a + L + t)⁻¹ ⊗ q(a + t))),   t < D
    q_loop(t) = q(a + t),                                                   D ≤ t < L
    w(t) = smoothstep(t / D) = 3u² − 2u³,  u = t / D

so the loop's last frame ``q(a + L − 1)`` is followed by ``q_loop(0) = q(a + L)``, the step the
motion itself took there: pose and angular velocity go on across the wrap, and the blend's weight
has zero slope at both ends (no kink where it starts or stops). The loop is a cycle with no seam
of its own; it is made to start (:func:`calm_seam`) where the step into it and the change of step
are smallest, so the exported clip's first and last frames meet where the tree moves least.
The window's start ``a`` is the one whose blend has the least to do (the smallest mean squared
angle between ``q(a + L + t)`` and ``q(a + t)`` over the blend, every bone). A loop as long as
the clip or longer takes the whole clip: ``L = F − D``. A generated tree grown for the loop
(``GrowParams.loop_s``: frequencies on whole periods, ``meta["periodic"]``) already repeats
exactly: nothing is blended.

The looped tree has ``L + 1`` frames, the last equal to the first (an engine interpolating from
the last key back to the first plays the seam as one ordinary step). Leaf flutter is played as its
steady sine (as Blender plays it, :func:`core.keys.steady_flutter`) at the nearest frequency with
a whole number of periods in the loop, and so is every leaf's flap: they loop too.

:func:`seam_jumps` measures a loop's seam against the clip's own steps (the tests' bounds: pose
jump ≤ the clip's median per-frame step, velocity jump ≤ 2 × it).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from . import bones
from .errors import InputError
from .keys import dominant_hz, steady_coefficients
from .meta import TreeMeta
from .params import param
from .rotations import make_continuous, quat_conj, quat_exp, quat_log, quat_mul
from .tree3d import Tree3D


@dataclass
class LoopSettings:
    """``seconds`` of the loop the Blender outputs and exports carry (0: the clip as measured, no
    loop; longer than the clip: the whole clip, its seam blended). The CLI's ``--loop`` and the
    panel's *Loop* read this default and range."""

    seconds: float = param(0.0, 0.0, 3600.0, what="--loop", unit="s")


#: seconds of the blend across the seam (at most a quarter of the loop)
BLEND_S = 1.0
#: the shortest loop, frames
MIN_FRAMES = 8


@dataclass
class LoopReport:
    """How a loop was cut: ``frames`` L (the looped tree has L + 1), ``start`` the clip frame the
    loop starts at (the window's first frame plus the calm seam's offset), ``blend`` D frames,
    ``seconds`` L / fps, ``whole_clip`` the loop took the clip (shortened by the blend),
    ``flutter_hz`` and ``flap_hz`` the leaves' loop frequencies (0: none), ``mismatch_deg`` the
    RMS angle the blend bridged."""

    frames: int
    start: int
    blend: int
    seconds: float
    whole_clip: bool
    flutter_hz: float
    flap_hz: float
    mismatch_deg: float

    def as_meta(self) -> dict:
        return {"frames": self.frames, "start": self.start, "blend": self.blend, "seconds": round(self.seconds, 4),
                "whole_clip": self.whole_clip, "flutter_hz": round(self.flutter_hz, 5),
                "flap_hz": round(self.flap_hz, 5), "mismatch_deg": round(self.mismatch_deg, 3)}


def smoothstep(u: np.ndarray) -> np.ndarray:
    """``3u² − 2u³`` on [0, 1] (0 and 1 with zero slope at the ends)."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def loop_frequency(hz: float, frames: int, fps: float) -> float:
    """The frequency nearest ``hz`` with a whole number (≥ 1) of periods in ``frames / fps`` s."""
    if not hz > 0:
        return 0.0
    seconds = frames / float(fps)
    return max(1, int(round(hz * seconds))) / seconds


def _window_cost(q: np.ndarray, L: int, D: int) -> np.ndarray:
    """``(F − L − D + 1,)`` mean squared angle (rad²) between ``q(a + L + t)`` and ``q(a + t)``
    over ``t < D`` and every bone, per window start ``a``; ``q (F, B, 4)``."""
    F = len(q)
    starts = F - L - D + 1
    # the angle between every frame and the frame L later, (F - L, B), then a running mean over D
    rel = quat_mul(quat_conj(q[:F - L]), q[L:])
    ang2 = np.sum(quat_log(rel) ** 2, axis=-1).mean(axis=1)
    c = np.concatenate([[0.0], np.cumsum(ang2)])
    return (c[D:D + starts] - c[:starts]) / D


def loop_rotations(q: np.ndarray, L: int, D: int, start: int | None = None) -> tuple[np.ndarray, int, float]:
    """The loop's rotations ``(L, B, 4)`` from ``q (F, B, 4)`` (module docstring), its window start
    and the RMS angle (radians) the blend bridged. ``start`` None: the best window."""
    q = make_continuous(np.asarray(q, np.float64))
    F = len(q)
    if L + D > F:
        raise ValueError(f"a loop of {L} frames with a {D}-frame blend needs {L + D} frames; the clip has {F}")
    cost = _window_cost(q, L, D)
    a = int(np.argmin(cost)) if start is None else int(start)
    out = q[a:a + L].copy()
    t = np.arange(D)
    w = smoothstep(t / D)[:, None, None]
    after, own = q[a + L:a + L + D], q[a:a + D]
    rel = quat_mul(quat_conj(after), own)
    rel = np.where(rel[..., :1] < 0, -rel, rel)                      # the short way round
    out[:D] = quat_mul(after, quat_exp(w * quat_log(rel)))
    r = calm_seam(out, clip_step(q))
    return np.roll(out, -r, axis=0), a + r, float(np.sqrt(cost[a]))


def _steps(q: np.ndarray, cyclic: bool = True) -> np.ndarray:
    """Rotation vectors ``(L, B, 3)`` of each step ``t → t + 1`` of the cyclic ``q (L, B, 4)``
    (``L − 1`` of them when not ``cyclic``)."""
    if cyclic:
        q = np.concatenate([q, q[:1]])
    return quat_log(quat_mul(quat_conj(q[:-1]), q[1:]))


def _rms_bones(v: np.ndarray) -> np.ndarray:
    """``(T,)`` the RMS over bones of the rotation vectors ``v (T, B, 3)`` (radians)."""
    return np.sqrt(np.mean(np.sum(v ** 2, axis=-1), axis=1))


def calm_seam(q: np.ndarray, step: float) -> int:
    """The frame of the cyclic ``q (L, B, 4)`` to start the loop at: where the step into it and the
    change of step there are smallest against the clip's median ``step`` (radians; the seam's
    bounds, :func:`seam_jumps`). Any frame of a smooth loop would do; the calmest keeps the
    engine's wrap (where some players blend or re-sync) where the tree moves least."""
    st = _steps(q)                                                    # st[t]: t → t + 1
    speed = _rms_bones(st)                                            # into frame t + 1
    change = _rms_bones(st - np.roll(st, 1, axis=0))
    score = np.maximum(speed / max(step, 1e-12), change / max(2 * step, 1e-12))
    return int((np.argmin(score) + 1) % len(q))


def seam_jumps(q: np.ndarray) -> tuple[float, float, float]:
    """For a cyclic sequence ``q (L, B, 4)`` (frame L would be frame 0): the RMS over bones of the
    step across the seam (L − 1 → 0), of the change of step there (|ω(L−1 → 0) − ω(L−2 → L−1)|,
    the velocity jump, radians per frame), and the median over the sequence's other frames of
    the RMS step — all radians."""
    steps = _steps(np.asarray(q, np.float64))                           # (L, B, 3): step t → t + 1
    rms = _rms_bones(steps)                                             # (L,)
    seam = float(rms[-1])
    vel = float(_rms_bones((steps[-1] - steps[-2])[None])[0])
    return seam, vel, float(np.median(rms[:-1]))


def clip_step(q: np.ndarray) -> float:
    """The clip's median per-frame step: median over frames of the RMS over bones of the rotation
    from one frame to the next, radians."""
    return float(np.median(_rms_bones(_steps(np.asarray(q, np.float64), cyclic=False))))


def loop_tree(tree: Tree3D, seconds: float) -> tuple[Tree3D, LoopReport]:
    """``tree`` cut to a seamless loop of about ``seconds`` (module docstring): ``L + 1`` frames,
    evenly timed at the tree's fps (a variable frame rate's timestamps are dropped), the leaves'
    flutter and flap at loop frequencies; ``meta["loop"]`` records the :class:`LoopReport`."""
    fps = float(tree.fps)
    if not seconds > 0:
        raise InputError(f"loop length {seconds} s: give a positive number of seconds, e.g. 10")
    F = tree.n_frames
    want = int(round(seconds * fps))
    rest_pos = np.asarray(tree.nodes3d[0], np.float64)
    rest = bones.rest_frames(tree.parents, rest_pos)
    local = bones.local_rotations(tree.parents, tree.nodes3d, rest)
    periodic = tree.meta.get("periodic")
    if periodic and abs(int(periodic["frames"]) - want) <= 1 and F == int(periodic["frames"]) + 1:
        # grown on whole periods (growth.grow_tree): already a loop, nothing to blend
        L, D, whole, bridged = F - 1, 0, True, 0.0
        q = make_continuous(local[:L])
        a = calm_seam(q, clip_step(local))
        q = np.roll(q, -a, axis=0)
    else:
        D = int(np.clip(round(BLEND_S * fps), 2, max(2, min(want, F) // 4)))
        whole = want + D > F
        L = F - D if whole else want
        if L < MIN_FRAMES:
            raise InputError(f"the clip's {F} frames make no loop ({L} frames after a {D}-frame blend); "
                             f"reconstruct at least {MIN_FRAMES + 2 * D} frames or drop --loop")
        q, a, bridged = loop_rotations(local, L, D)
    q = np.concatenate([q, q[:1]])                                   # frame L = frame 0
    nodes = bones.pose(tree.parents, rest_pos, rest, q)[0].astype(np.float32)
    leaves = tree.leaves
    flutter_hz = flap_hz = 0.0
    if leaves is not None and leaves.count > 0:
        hz = leaves.flutter_hz or dominant_hz(leaves.flutter, fps)
        flutter_hz = loop_frequency(hz, L, fps)
        flap_hz = loop_frequency(leaves.leaf_hz, L, fps)
        t = np.arange(L + 1) / fps
        if flutter_hz > 0:
            coef = steady_coefficients(leaves.flutter, fps, hz)
            w = 2 * np.pi * flutter_hz
            flutter = np.stack([np.sin(w * t), np.cos(w * t)], axis=1) @ coef
        else:
            flutter = np.zeros((L + 1, leaves.count))
        leaves = replace(leaves, flutter=flutter.astype(np.float32), flutter_hz=flutter_hz, leaf_hz=flap_hz)
    report = LoopReport(L, a, D, L / fps, whole, flutter_hz, flap_hz, float(np.degrees(bridged)))
    meta: TreeMeta = {**tree.meta, "loop": report.as_meta()}
    looped = replace(tree, nodes3d=nodes, leaves=leaves, times=None, meta=meta)
    return looped, report


def describe_loop(report: LoopReport, fps: float) -> str:
    """One line for the log and the panel: the loop's length, where it starts, the blend."""
    leaves = f"; leaf flutter {report.flutter_hz:.2f} Hz" if report.flutter_hz > 0 else ""
    if report.blend == 0:
        return f"a {report.seconds:.2f} s loop of {report.frames} frames, grown on whole periods (nothing blended){leaves}"
    whole = " (the whole clip less its blend)" if report.whole_clip else ""
    return (f"a {report.seconds:.2f} s loop of {report.frames} frames{whole} from frame {report.start}, "
            f"{report.blend / fps:.2f} s blended across {report.mismatch_deg:.1f}° at its seam{leaves}")


def maybe_loop(tree: Tree3D, seconds: float) -> tuple[Tree3D, str | None]:
    """``tree`` looped to ``seconds`` with its one-line description, or ``tree`` and None when
    ``seconds`` is 0 (no loop asked for): what the panel and the batch do before building."""
    if not seconds > 0:
        return tree, None
    looped, cut = loop_tree(tree, seconds)
    return looped, f"'{tree.name}': {describe_loop(cut, tree.fps)}"
