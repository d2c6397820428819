"""Keys only where the motion needs them (issue 32): which frames of each bone's rotation a
Blender F-curve keys so that no node of the tree strays more than a tolerance from where the full
per-frame motion puts it, and how it keys them. Pure numpy: the Blender writer keys what this
keeps, and an engine export can.

Tolerance. :data:`KEY_TOLERANCE` of the tree's height ``H`` in node (bone-tip) position: 0.1 % of
``H``, one pixel when the tree fills a 1080p frame's height.

Keys (:func:`reduce_keys`). Smooth keys: Bezier keys whose handles lie a third of the span away
along each key's slope (:func:`slopes`, :func:`handles`), so Blender plays the cubic Hermite
(:func:`hermite`) between them, per quaternion channel, normalized when posed. Between two kept
keys bone ``b``'s pose is off by an angle ``δ_b`` (of the rotation between the normalized
interpolation and the true quaternion); a node below ``b`` then moves by at most about
``δ_b · r_b``, ``r_b`` the farthest any node of ``b``'s subtree lies from ``b``'s head at rest
(:func:`bone_reach`). Each bone first gets ``δ_b = tol / (r_b · √n_b)``, ``n_b`` the most bones on
any root-to-tip chain through ``b`` (:func:`chain_bones`: errors along a chain of independent bones
add like a random walk, not all in one direction). The kept keys are found by dyadic refinement:
the first and last frame, then the middle of every span whose interpolation strays more than
``δ_b``, down to single frames, vectorized over bones and spans.

Samples. A measured motion jitters from frame to frame by about the tolerance (a reconstructed
tree's second differences are 0.05–0.1 % of ``H``), so its bones keep 40–70 % of their keys; a bone
keeping more than :data:`SAMPLE_SHARE` is stored as one baked sample per frame instead (Blender's
``FCurve.convert_to_samples``: exact, and a quarter of a key's bytes). A generated tree's smooth
sway keeps a fraction of its keys.

Check (:func:`pose_keys`). The reduced curves are then posed at every frame by forward kinematics
(:func:`.bones.pose`) against the full ones, the bones' tails and the points they carry (the leaf
clusters' centres, which also count in ``r_b``); where one strays more than ``tol``, every bone of
its chain has its ``δ_b`` halved and is reduced again. After :data:`ROUNDS` rounds the
guaranteed split ``δ_b = tol / (r_b · n_b)`` (the chain's errors all in one direction) is used,
so the result always holds at every frame.

Leaf flutter (:func:`steady_flutter`). A cluster's flutter ``A(t) sin(ωt + β)`` is invented detail
(paper Appendix B.2: its amplitude follows the branch's speed), not a measurement, and a key per
cluster per frame is most of a leafy tree's keys (619 clusters × 2 channels against 331 branch
bones × 4). Blender plays it as a steady sine, one period of keys under a *Cycles* modifier: each
cluster's least-squares fit ``a sin(ωt) + b cos(ωt)`` of the stored flutter (its amplitude about
the mean of ``A(t)``), keyed at every frame of one period ``fps / (ω / 2π)`` frames and at the
period's end. The stored model keeps the full flutter.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bones import bone_depths, bone_edges, bone_parents, local_rotations, pose
from .rotations import quat_rotate

#: the largest error the reduced keys may add to any node's position, a share of the tree height
KEY_TOLERANCE = 0.001
#: reductions checked by forward kinematics before falling back to the guaranteed bound
ROUNDS = 6
#: bytes one Bezier key and one baked sample of an F-curve take in a .blend (measured: a 555-frame
#: tree's .blend with 542 k keys, and again with its branch curves baked to 684 k samples)
KEY_BYTES = 85
SAMPLE_BYTES = 21
#: a bone keeping more than this share of its frames as keys is stored as one sample per frame
#: instead (exact, and smaller: a measured tree's frame-to-frame jitter keeps 40–70 % of its keys)
SAMPLE_SHARE = SAMPLE_BYTES / KEY_BYTES


@dataclass
class ReducedKeys:
    """``keep (F, B)`` bool: the frames each bone keys (first and last always); ``error`` the
    largest node position error of the reduced curves over every frame (metres), ``tolerance``
    the bound it was reduced to (metres)."""
    keep: np.ndarray
    error: float
    tolerance: float


def bone_reach(parents: np.ndarray, rest_positions: np.ndarray, points: np.ndarray | None = None,
               point_bones: np.ndarray | None = None) -> np.ndarray:
    """``(B,)`` metres: for each bone (:func:`.bones.bone_edges` order), the largest rest distance
    from its head to any node of its subtree (its own tail included) or to any of ``points (P, 3)``
    carried by a bone of its subtree (``point_bones (P,)``: leaf clusters)."""
    edges = bone_edges(parents)
    rest = np.asarray(rest_positions, np.float64)
    pb = bone_parents(parents)
    B = len(edges)
    reach = np.zeros(B)
    if B == 0:
        return reach
    far = rest[edges[:, 1]]                 # each carried point, and the bone that carries it
    by = np.arange(B)
    if points is not None and len(points):
        far = np.vstack([far, np.asarray(points, np.float64)])
        by = np.concatenate([by, np.asarray(point_bones)])
    anc = by.copy()                         # walk every point up through its bone's ancestors
    for _ in range(int(bone_depths(pb).max()) + 1):
        ok = anc >= 0
        a = anc[ok]
        d = np.linalg.norm(far[ok] - rest[edges[a, 0]], axis=1)
        np.maximum.at(reach, a, d)
        anc = np.where(ok, pb[np.maximum(anc, 0)], -1)
    return reach


def bones_into(parents: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """``(K,)`` the bone carrying each of ``nodes``: the bone into the node, for the root (node 0)
    its first child's (as leaf clusters ride, :class:`.tree3d.LeafClusters`)."""
    edges = bone_edges(parents)
    of = np.full(len(parents), -1)
    of[edges[:, 1]] = np.arange(len(edges))
    first = np.flatnonzero(edges[:, 0] == 0)
    if len(first):
        of[0] = first[0]
    return of[np.asarray(nodes)]


def chain_bones(parents: np.ndarray) -> np.ndarray:
    """``(B,)``: the most bones on any root-to-tip chain through each bone (its depth + 1 + the
    longest chain below it)."""
    pb = bone_parents(parents)
    B = len(pb)
    if B == 0:
        return np.zeros(0, np.int64)
    depth = bone_depths(pb)
    below = np.zeros(B, np.int64)                       # bones under b on its longest chain
    for d in range(int(depth.max()), 0, -1):
        idx = np.flatnonzero(depth == d)
        np.maximum.at(below, pb[idx], below[idx] + 1)
    return depth + 1 + below


def slopes(q: np.ndarray, times: np.ndarray | None = None) -> np.ndarray:
    """``(F, B, 4)``: each channel's rate of change per frame of ``times (F,)`` at every frame
    (central differences; one-sided at the ends) — the tangents the smooth keys' handles carry."""
    q = np.asarray(q, np.float64)
    F = len(q)
    t = np.arange(F, dtype=np.float64) if times is None else np.asarray(times, np.float64)
    if F < 2:
        return np.zeros_like(q)
    lo = np.maximum(np.arange(F) - 1, 0)
    hi = np.minimum(np.arange(F) + 1, F - 1)
    return (q[hi] - q[lo]) / np.maximum(t[hi] - t[lo], 1e-12)[:, None, None]


def hermite(qa: np.ndarray, qb: np.ndarray, ma: np.ndarray, mb: np.ndarray, span: np.ndarray,
            u: np.ndarray) -> np.ndarray:
    """The cubic through ``qa`` → ``qb`` with slopes ``ma``, ``mb`` (per frame) over ``span`` frames at
    fractions ``u`` (all broadcast; the quaternion axis last): what a Bezier F-curve plays between
    two keys whose handles lie a third of the span away along those slopes,
    ``h00 qa + h10 Δ ma + h01 qb + h11 Δ mb`` (h00 = 2u³ − 3u² + 1, h10 = u³ − 2u² + u,
    h01 = −2u³ + 3u², h11 = u³ − u²)."""
    u2, u3 = u * u, u * u * u
    return ((2 * u3 - 3 * u2 + 1) * qa + (u3 - 2 * u2 + u) * span * ma
            + (-2 * u3 + 3 * u2) * qb + (u3 - u2) * span * mb)


def interpolation_error(q: np.ndarray, times: np.ndarray, a: np.ndarray, b: np.ndarray,
                        m: np.ndarray | None = None) -> np.ndarray:
    """``(S, B)`` radians: over each span ``a[s] .. b[s]`` (frame indices), the largest angle between
    the quaternions ``q (F, B, 4)`` and their interpolation between frames ``a`` and ``b`` (in
    ``times (F,)``), normalized: linear, or with ``m (F, B, 4)`` (:func:`slopes`) the cubic
    :func:`hermite`."""
    width = int(np.max(b - a)) + 1
    idx = np.minimum(a[:, None] + np.arange(width)[None], b[:, None])      # (S, W) frames in the span
    span = np.maximum(times[b] - times[a], 1e-12)
    w = ((times[idx] - times[a][:, None]) / span[:, None])[..., None, None]   # (S, W, 1, 1)
    if m is None:
        est = (1 - w) * q[a][:, None] + w * q[b][:, None]                   # (S, W, B, 4)
    else:
        est = hermite(q[a][:, None], q[b][:, None], m[a][:, None], m[b][:, None], span[:, None, None, None], w)
    est /= np.maximum(np.linalg.norm(est, axis=-1, keepdims=True), 1e-12)
    return rotation_angle(est, q[idx]).max(axis=1)


def rotation_angle(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Radians of the rotation between unit quaternions ``q1`` and ``q2`` (``(..., 4)``, either
    sign): twice their angle on the 4-sphere, from the chord (``4 asin(|q1 ∓ q2| / 2)``), exact
    near zero where ``2 acos |q1·q2|`` loses half its digits."""
    sign = np.where(np.sum(q1 * q2, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    chord = np.linalg.norm(q1 - sign * q2, axis=-1)
    return 4.0 * np.arcsin(np.clip(0.5 * chord, 0.0, 1.0))


def reduce_keys(q: np.ndarray, tol_rad: np.ndarray | float, times: np.ndarray | None = None,
                smooth: bool = True) -> np.ndarray:
    """``(F, B)`` bool: the frames each bone's keys keep so that the interpolation of ``q (F, B, 4)``
    (continuous signs, :func:`.rotations.make_continuous`) between kept keys — the cubic
    :func:`hermite` with :func:`slopes`, or linear when not ``smooth`` — stays within ``tol_rad (B,)``
    radians at every frame; ``times (F,)`` the keys' frames (default 0..F-1). The first and last
    frames are always kept."""
    q = np.asarray(q, np.float64)
    F, B = q.shape[:2]
    t = np.arange(F, dtype=np.float64) if times is None else np.asarray(times, np.float64)
    keep = np.zeros((F, B), bool)
    if F == 0:
        return keep
    keep[0] = keep[-1] = True
    if F <= 2:
        return keep
    m = slopes(q, t) if smooth else None
    tol = np.broadcast_to(np.asarray(tol_rad, np.float64), (B,))
    s = 1 << int(np.ceil(np.log2(F - 1)))
    while s >= 2:
        a = np.arange(0, F - 1, s)
        b = np.minimum(a + s, F - 1)
        mid = a + s // 2
        ok = mid < b
        a, b, mid = a[ok], b[ok], mid[ok]
        if len(a):
            active = keep[a] & keep[b]                                    # (S, B): spans of kept keys
            rows = np.flatnonzero(active.any(axis=1))
            chunk = max(1, 2_000_000 // max(s * B, 1))                    # bounded memory
            for lo in range(0, len(rows), chunk):
                r = rows[lo:lo + chunk]
                err = interpolation_error(q, t, a[r], b[r], m)
                keep[mid[r]] |= active[r] & (err > tol[None])
        s //= 2
    return keep


def interpolate(q: np.ndarray, keep: np.ndarray, times: np.ndarray | None = None,
                smooth: bool = True) -> np.ndarray:
    """``(F, B, 4)``: the curves through ``q``'s kept keys (``keep (F, B)``, first and last kept) —
    the cubic :func:`hermite` with :func:`slopes` (what Blender's Bezier keys with
    :func:`handles` play), or linear (LINEAR keys, a LINEAR glTF sampler) when not ``smooth`` —
    normalized, at every frame."""
    q = np.asarray(q, np.float64)
    F, B = keep.shape
    t = np.arange(F, dtype=np.float64) if times is None else np.asarray(times, np.float64)
    prev, nxt = _kept_around(keep)
    prev, nxt = np.maximum(prev, 0), np.minimum(nxt, F - 1)
    span = np.maximum(t[nxt] - t[prev], 1e-12)
    w = (t[:, None] - t[prev]) / span
    cols = np.arange(B)[None]
    if smooth:
        m = slopes(q, t)
        out = hermite(q[prev, cols], q[nxt, cols], m[prev, cols], m[nxt, cols], span[..., None], w[..., None])
    else:
        out = (1 - w)[..., None] * q[prev, cols] + w[..., None] * q[nxt, cols]
    return out / np.maximum(np.linalg.norm(out, axis=-1, keepdims=True), 1e-12)


def _kept_around(keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(prev, next)``, each ``(F, B)``: at every frame the last kept frame at or before it (−1 when
    none) and the first at or after it (``F`` when none)."""
    F = len(keep)
    idx = np.arange(F)[:, None]
    prev = np.maximum.accumulate(np.where(keep, idx, -1), axis=0)
    nxt = np.flip(np.minimum.accumulate(np.flip(np.where(keep, idx, F), 0), axis=0), 0)
    return prev, nxt


def handles(q: np.ndarray, keep: np.ndarray, times: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The Bezier handles of the kept keys that make Blender play :func:`interpolate`: ``(left,
    right)``, each ``(F, B, 4, 2)`` (frame, value) at every frame (read where ``keep``): a third of
    the span to the previous / next kept key away, along the key's :func:`slopes` (the first key's
    left and the last key's right handle mirror their other side)."""
    q = np.asarray(q, np.float64)
    F, B = keep.shape
    t = np.arange(F, dtype=np.float64) if times is None else np.asarray(times, np.float64)
    m = slopes(q, t)
    prev, nxt = _kept_around(keep)
    # the previous and next kept key of every kept key (itself excluded): one row earlier / later
    before = np.vstack([np.full((1, B), -1), prev[:-1]])
    after = np.vstack([nxt[1:], np.full((1, B), F)])
    dl = np.where(before >= 0, t[:, None] - t[np.maximum(before, 0)], 0.0)
    dr = np.where(after < F, t[np.minimum(after, F - 1)] - t[:, None], 0.0)
    dl, dr = np.where(dl > 0, dl, dr), np.where(dr > 0, dr, dl)            # the ends mirror
    left = np.stack([np.broadcast_to((t[:, None] - dl / 3)[..., None], q.shape), q - m * (dl / 3)[..., None]], -1)
    right = np.stack([np.broadcast_to((t[:, None] + dr / 3)[..., None], q.shape), q + m * (dr / 3)[..., None]], -1)
    return left, right


def _chains(parents: np.ndarray, bones_: np.ndarray) -> np.ndarray:
    """``(B,)`` bool: the bones on the root-to-bone chains of ``bones_``."""
    pb = bone_parents(parents)
    on = np.zeros(len(pb), bool)
    cur = np.asarray(bones_)
    cur = cur[cur >= 0]
    while len(cur):
        on[cur] = True
        cur = pb[cur]
        cur = cur[(cur >= 0) & ~on[np.maximum(cur, 0)]]
    return on


def _errors(parents, rest, rest_matrices, local, keep, times, full, points, point_bones):
    """Per bone ``(B,)`` metres: the largest error over every frame of its tail and of the points it
    carries, posed from the kept keys against ``full`` (:func:`_posed` of the full motion)."""
    got = _posed(parents, rest, rest_matrices, interpolate(local, keep, times), points, point_bones)
    err = np.linalg.norm(got - full, axis=-1).max(axis=0)             # (B + P,)
    B = len(bone_edges(parents))
    out = err[:B].copy()
    if points is not None and len(points):
        np.maximum.at(out, point_bones, err[B:])
    return out


def _posed(parents, rest, rest_matrices, local, points, point_bones) -> np.ndarray:
    """``(F, B + P, 3)``: the bones' tails and the carried ``points`` posed by ``local``."""
    tails, qw = pose(parents, rest, rest_matrices, local)
    edges = bone_edges(parents)
    out = tails[:, edges[:, 1]]
    if points is None or not len(points):
        return out
    head = edges[point_bones, 0]
    offset = np.asarray(points, np.float64) - rest[head]
    carried = tails[:, head] + quat_rotate(qw[:, point_bones], offset[None])
    return np.concatenate([out, carried], axis=1)


def pose_keys(parents: np.ndarray, rest_positions: np.ndarray, rest_matrices: np.ndarray,
              local: np.ndarray, times: np.ndarray | None = None,
              tolerance: float | None = None, points: np.ndarray | None = None,
              point_bones: np.ndarray | None = None) -> ReducedKeys:
    """The keys of the pose ``local (F, B, 4)`` (:func:`.bones.local_rotations`) that keep every
    node, and every one of ``points (P, 3)`` carried by the bones ``point_bones (P,)`` (leaf
    clusters' centres), within ``tolerance`` metres (default :data:`KEY_TOLERANCE` × the rest
    height) of the full motion at every frame; ``rest_positions (N, 3)`` metres, ``rest_matrices
    (B, 3, 3)``, ``times (F,)`` the keys' frames. See the module docstring."""
    rest = np.asarray(rest_positions, np.float64)
    local = np.asarray(local, np.float64)
    F, B = local.shape[:2]
    height = max(float(np.ptp(rest[:, 2])) if len(rest) else 0.0, 1e-6)
    tol = KEY_TOLERANCE * height if tolerance is None else float(tolerance)
    if F <= 2 or B == 0:
        return ReducedKeys(np.ones((F, B), bool), 0.0, tol)
    reach = np.maximum(bone_reach(parents, rest, points, point_bones), 1e-9)
    n = chain_bones(parents)
    full = _posed(parents, rest, rest_matrices, local, points, point_bones)
    delta = tol / (reach * np.sqrt(n))
    for _ in range(ROUNDS):
        keep = _sampled_where_dense(reduce_keys(local, delta, times))
        err = _errors(parents, rest, rest_matrices, local, keep, times, full, points, point_bones)
        bad = np.flatnonzero(err > tol)
        if len(bad) == 0:
            return ReducedKeys(keep, float(err.max()), tol)
        delta = np.where(_chains(parents, bad), 0.5 * delta, delta)
    keep = _sampled_where_dense(reduce_keys(local, tol / (reach * n), times))    # the guaranteed bound
    err = _errors(parents, rest, rest_matrices, local, keep, times, full, points, point_bones)
    return ReducedKeys(keep, float(err.max()), tol)


def _sampled_where_dense(keep: np.ndarray) -> np.ndarray:
    """``keep`` with every frame kept for the bones keeping more than :data:`SAMPLE_SHARE` of them
    (the writer stores those as samples: exact and smaller)."""
    dense = keep.mean(axis=0) > SAMPLE_SHARE
    keep[:, dense] = True
    return keep


def flutter_quaternions(angles: np.ndarray) -> np.ndarray:
    """``(..., 4)`` (w, x, y, z) rotations by ``angles (...)`` radians about the bone's Y axis (a
    leaf cluster's flutter turn)."""
    half = 0.5 * np.asarray(angles, np.float64)
    q = np.zeros(half.shape + (4,))
    q[..., 0], q[..., 2] = np.cos(half), np.sin(half)
    return q


def angle_keys(angles: np.ndarray, tol_rad: np.ndarray | float, times: np.ndarray | None = None) -> np.ndarray:
    """``(F, S)`` bool: the frames that keep a turn by ``angles (F, S)`` radians about a fixed axis
    (a leaf cluster's flutter) within ``tol_rad (S,)`` of its full curve when keyed linearly (as the
    leaf bones are: ``operators/scene/leaves.py``)."""
    return reduce_keys(flutter_quaternions(angles), tol_rad, times, smooth=False)


@dataclass
class SteadyFlutter:
    """One period of every leaf cluster's steady flutter: ``frames (K,)`` scene-frame offsets from
    the first frame (0, 1, …, and the period ``frames[-1]``, where the cycle closes: its angles equal
    the first), ``angles (K, S)`` radians; ``played (F, S)`` radians what the cycle plays at the
    tree's frames (for tests and previews)."""
    frames: np.ndarray
    angles: np.ndarray
    played: np.ndarray

    @property
    def period(self) -> float:
        """Frames of one cycle."""
        return float(self.frames[-1])


def steady_coefficients(flutter: np.ndarray, fps: float, hz: float) -> np.ndarray:
    """``(2, S)`` the least-squares ``a sin(ωt) + b cos(ωt)`` (ω = 2π·``hz``, ``t = index / fps``)
    of each cluster's ``flutter (F, S)`` radians."""
    t = np.arange(len(flutter)) / float(fps)
    w = 2 * np.pi * float(hz)
    X = np.stack([np.sin(w * t), np.cos(w * t)], axis=1)              # (F, 2)
    coef, *_ = np.linalg.lstsq(X, np.asarray(flutter, np.float64), rcond=None)
    return coef


def steady_flutter(flutter: np.ndarray, fps: float, hz: float, frames: np.ndarray | None = None) -> SteadyFlutter | None:
    """The steady sine that best fits each cluster's ``flutter (F, S)`` radians at ``hz`` (the
    flutter's ω / 2π; made at ``index / fps`` seconds, :func:`.detail.leaf_clusters.flutter_angles`),
    keyed over one period (see the module docstring), or None when the clip is shorter than two
    periods or ``hz`` is unknown (0): then the flutter is keyed frame by frame. ``frames (F,)`` the
    scene frames the tree's frames play at (:func:`.tree3d.key_frames`; default ``1..F``), for
    ``played``."""
    flutter = np.asarray(flutter, np.float64)
    F = len(flutter)
    if not hz > 0 or not fps > 0:
        return None
    period = float(fps) / float(hz)                                   # scene frames
    if F < 2 * period + 1:
        return None
    w = 2 * np.pi * float(hz)
    coef = steady_coefficients(flutter, fps, hz)                      # (2, S)
    k = np.arange(int(np.floor(period)) + 1, dtype=np.float64)
    if period - k[-1] > 1e-6:
        k = np.append(k, period)
    tk = k / float(fps)
    angles = np.stack([np.sin(w * tk), np.cos(w * tk)], axis=1) @ coef
    angles[-1] = angles[0] if k[-1] == period else angles[-1]         # close the cycle exactly
    # what Blender plays at the tree's scene frames: the cycle, linear between its keys
    at = np.arange(F, dtype=np.float64) if frames is None else np.asarray(frames, np.float64) - float(frames[0])
    phase = np.mod(at, period)
    played = np.stack([np.interp(phase, k, angles[:, s]) for s in range(angles.shape[1])], axis=1) \
        if angles.shape[1] else np.zeros((F, 0))
    return SteadyFlutter(k, angles, played)


def dominant_hz(signals: np.ndarray, fps: float) -> float:
    """Hz of the strongest frequency of ``signals (F, S)`` (their power spectra summed, zero-padded
    8 ×, the peak refined by a parabola through its bins); 0 for fewer than 8 frames. For trees
    saved before their flutter's frequency was."""
    x = np.asarray(signals, np.float64)
    F = len(x)
    if F < 8 or not fps > 0:
        return 0.0
    x = x - x.mean(axis=0)
    n = 8 * F
    power = (np.abs(np.fft.rfft(x * np.hanning(F)[:, None], n=n, axis=0)) ** 2).sum(axis=1)
    power[0] = 0.0
    k = int(np.argmax(power))
    peak = float(k)
    if 0 < k < len(power) - 1:
        a, b, c = power[k - 1], power[k], power[k + 1]
        den = a - 2 * b + c
        peak += 0.5 * (a - c) / den if den < 0 else 0.0
    return peak * fps / n


@dataclass
class TreeKeys:
    """The keys a tree's animation keeps: ``bones (F, B)`` for the branch bones
    (:func:`.bones.bone_edges` order); the leaf clusters' flutter as one steady ``cycle``
    (:class:`SteadyFlutter`), or where it cannot be (a short clip, an old file), ``leaves (F, S)``
    its kept frames; both None without leaves. ``error`` metres, the branch nodes' largest error
    over every frame; ``tolerance`` metres."""
    bones: np.ndarray
    leaves: np.ndarray | None
    error: float
    tolerance: float
    cycle: SteadyFlutter | None = None

    @property
    def share(self) -> float:
        """Kept keys over all keys of the full animation (4 channels per branch bone, 2 per leaf)."""
        kept = 4 * self.bones.sum()
        total = 4 * self.bones.size
        if self.leaves is not None:
            kept, total = kept + 2 * self.leaves.sum(), total + 2 * self.leaves.size
        if self.cycle is not None:
            F = len(self.bones)
            kept, total = kept + 2 * self.cycle.angles.size, total + 2 * F * self.cycle.angles.shape[1]
        return float(kept / total) if total else 1.0


def tree_keys(tree, rest_matrices: np.ndarray, times: np.ndarray | None = None,
              tolerance: float | None = None, local: np.ndarray | None = None) -> TreeKeys:
    """The kept keys of ``tree`` (a :class:`.tree3d.Tree3D`) posed from ``rest_matrices (B, 3, 3)``
    (Blender's ``bone.matrix_local``, :func:`.bones.rest_frames` without Blender) at the keys'
    frames ``times (F,)`` (``local``: its :func:`.bones.local_rotations` when already computed):
    its branch bones by :func:`pose_keys`; the leaf clusters' flutter as one steady cycle
    (:func:`steady_flutter`), or where it cannot be, each cluster's frames so that its cards
    (within ``radius + leaf_size`` of the bone's axis) stray at most the same tolerance beyond
    where their branch carries them."""
    rest = np.asarray(tree.nodes3d[0], np.float64)
    if local is None:
        local = local_rotations(tree.parents, tree.nodes3d, rest_matrices)
    lv = tree.leaves
    with_leaves = lv is not None and lv.count > 0
    branch = pose_keys(tree.parents, rest, rest_matrices, local, times, tolerance,
                       lv.pos if with_leaves else None,
                       bones_into(tree.parents, lv.node) if with_leaves else None)
    leaf_keep = cycle = None
    if with_leaves:
        cycle = steady_flutter(lv.flutter, tree.fps, lv.flutter_hz or dominant_hz(lv.flutter, tree.fps), times)
        if cycle is None:
            reach = max(float(lv.radius) + float(lv.leaf_size), 1e-6)
            leaf_keep = angle_keys(lv.flutter, branch.tolerance / reach, times)
    return TreeKeys(branch.keep, leaf_keep, branch.error, branch.tolerance, cycle)
