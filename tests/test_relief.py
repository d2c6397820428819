"""Bark relief as geometry (issue 36 part 3, core/detail/relief.py): the bark's height map moves
the tubes' vertices along their rings' radial direction by the module's formula, checked by hand
on a fork with a known height map; on the broad sample's true tree the relief keeps the mesh closed
and outward, leaves a joined fork's rings where the junction meets them, and its depth on the trunk
is the one asked for; the photo bark's tiles repeat round the tube; the setting is recorded."""
import numpy as np
import pytest
from test_forks import _closed_outward, _fork

from tree_from_video.core import bones
from tree_from_video.core.asset import tree_asset
from tree_from_video.core.asset.meshes import branch_arrays, pipe_exponent, relief_height
from tree_from_video.core.detail import branch_mesh as bm
from tree_from_video.core.detail.relief import (
    BAND,
    FADE_RINGS,
    RELIEF_RINGS,
    RELIEF_SIDES,
    mesh_band,
    relief_offsets,
    sample_periodic,
)

from trees import broad_tree


def test_sample_periodic_by_hand():
    h = np.array([[0.0, 1.0], [2.0, 3.0]])             # rows v, columns u; texel centres at 1/4, 3/4
    uv = np.array([[0.25, 0.25], [0.75, 0.25], [0.5, 0.25], [0.0, 0.25], [0.25, 0.75], [0.25, 0.5], [1.25, -0.75]])
    np.testing.assert_allclose(sample_periodic(h, uv), [0.0, 1.0, 0.5, 0.5, 2.0, 1.0, 0.0])
    np.testing.assert_allclose(sample_periodic(h, np.array([[0.125, 0.125]]), repeats=2), [0.0])


def _tubes(tree, rings=RELIEF_RINGS, sides=RELIEF_SIDES, forks="joined"):
    P = tree.nodes3d[0].astype(np.float64)
    rest = bones.rest_frames(tree.parents, P)
    r_head, r_tail = bm.branch_radii(tree.parents, tree.radius)
    return bm.tube_arrays(P, tree.parents, rest, r_head, r_tail, sides, rings=rings, forks=forks,
                          pipe_exponent=pipe_exponent(tree))


def test_offsets_follow_the_formula_on_a_hand_fork():
    """h(u) = ½ + ½ sin(2π·4u) (columns only, 96 texels): each vertex moves along its ring's radial
    unit vector by relief · (h − mean h) / (max − min) · r0 / r_max, 0 on a junction's ring."""
    tree = _fork()
    g = _tubes(tree)
    W = 96
    col = 0.5 + 0.5 * np.sin(2 * np.pi * 4 * (np.arange(W) + 0.5) / W)
    height = np.tile(col, (8, 1))
    depth = 0.02
    off = relief_offsets(g, height, 1, depth)
    B, K, S = len(g["r0"]), int(g["rings"]), int(g["sides"])
    co = g["co"].reshape(B, K, S, 3)
    radial = co - g["centre"][:, :, None]
    radial /= np.linalg.norm(radial, axis=-1, keepdims=True)
    o = off.reshape(B, K, S, 3)
    along = np.einsum("bkso,bkso->bks", o, radial)
    across = np.linalg.norm(o - along[..., None] * radial, axis=-1)
    assert across.max() < 1e-12                                               # radial only
    # the expected offset: bilinear between the two texels either side of u = k/S + u0 (x = u·W − ½,
    # u0 the tube's upper side, branch_mesh.up_offsets); the low-pass keeps a pure sine's phase and
    # the peak-to-peak scaling undoes its gain
    k = np.arange(S)
    x = (k / S + g["u0"][..., None]) * W - 0.5
    x0 = np.floor(x).astype(int)
    fx = x - x0
    hk = (1 - fx) * col[x0 % W] + fx * col[(x0 + 1) % W]
    span = col.max() - col.min()
    expected = depth * (hk - col.mean()) / span                               # (S,) on the thickest ring
    plan = g["plan"]
    ramp = np.minimum(np.arange(K), FADE_RINGS) / FADE_RINGS
    w = g["r0"] / g["r0"].max()
    w = w * np.where(plan.head_cap[:, None], 1.0, ramp) * np.where(plan.tail_cap[:, None], 1.0, ramp[::-1])
    np.testing.assert_allclose(along, w[..., None] * expected, atol=1e-9)
    assert not plan.tail_cap[0] and np.abs(along[0, -1]).max() == 0.0        # the trunk's junction ring stays
    assert np.abs(along[0, K // 2]).max() > 0.4 * depth * w[0, K // 2]      # and the trunk's middle moves
    np.testing.assert_allclose(along.mean(axis=-1), 0.0, atol=1e-12)          # each ring keeps its mean radius


@pytest.fixture(scope="module")
def truth():
    return broad_tree(2)


def _as_dict(mesh) -> dict:
    return {"co": mesh.co.astype(np.float64), "loop_vert": mesh.loop_vert, "loop_start": mesh.loop_start,
            "loop_total": mesh.loop_total}


@pytest.mark.parametrize("forks", ["joined", "overlap"])
def test_relief_on_a_tree(truth, forks):
    """Procedural rough bark, 2 cm: the mesh stays closed and outward, the displacement is the
    sampled height (correlation), the trunk's peak-to-peak is the depth, twigs carry less."""
    rest = bones.rest_frames(truth.parents, truth.nodes3d[0])
    p = bm.MeshParams(curliness=0.3, bark="rough", forks=forks)
    flat = branch_arrays(truth, rest, bm.MeshParams(curliness=0.3, bark="rough", forks=forks,
                                                   sides=RELIEF_SIDES, rings=RELIEF_RINGS))
    depth_cm = 2.0
    relief = branch_arrays(truth, rest, bm.MeshParams(curliness=0.3, bark="rough", forks=forks, relief_cm=depth_cm))
    assert p.sides < RELIEF_SIDES and len(relief.co) == len(flat.co)          # densified to 24 × 12
    np.testing.assert_array_equal(relief.loop_vert, flat.loop_vert)
    closed, outward, _, _ = _closed_outward(_as_dict(relief))
    assert closed and outward
    d = (relief.co - flat.co).astype(np.float64)
    B, K, S = len(rest), RELIEF_RINGS, RELIEF_SIDES
    d = d.reshape(B, K, S, 3)
    mag = np.linalg.norm(d, axis=-1)
    # the trunk (bone 0): its middle rings' peak-to-peak along the radial, against the depth asked
    co = flat.co.reshape(B, K, S, 3).astype(np.float64)
    centre = co.mean(axis=2, keepdims=True)
    radial = (co - centre) / np.linalg.norm(co - centre, axis=-1, keepdims=True)
    along = np.einsum("bkso,bkso->bks", d, radial)
    mid = slice(FADE_RINGS, K - FADE_RINGS)
    ptp = np.ptp(along[0, mid], axis=-1)
    r0 = float(truth.radius.max())
    print(f"\n{forks}: trunk ring peak-to-peak {100 * ptp.min():.2f}–{100 * ptp.max():.2f} cm of {depth_cm} cm "
          f"(trunk radius {100 * r0:.1f} cm); largest move {100 * mag.max():.2f} cm")
    assert ptp.max() <= depth_cm / 100 + 1e-6 and np.median(ptp) > 0.3 * depth_cm / 100
    assert mag.max() <= depth_cm / 100 + 1e-6
    # the moves follow the height, low-passed to the vertex spacing (the mesh's band): correlation
    # on the trunk's middle rings; against the raw map it is lower (the cells the mesh cannot carry)
    raw = relief_height("rough")
    u0, v = _ring_uv(truth, rest, forks)
    H, W = raw.shape
    band = mesh_band(raw, BAND * W / S, BAND * H * np.median(np.diff(v, axis=1)))
    uv = np.stack([(np.arange(S) / S + u0[0][:, None])[mid].ravel(), v[0][mid].repeat(S)], axis=1)
    corr = np.corrcoef(sample_periodic(band, uv), along[0, mid].ravel())[0, 1]
    corr_raw = np.corrcoef(sample_periodic(raw, uv), along[0, mid].ravel())[0, 1]
    print(f"{forks}: trunk moves vs the mesh band of the height: correlation {corr:.4f} (raw map {corr_raw:.3f})")
    assert corr > 0.99 and corr_raw < corr
    # twigs carry thinner bark: the thinnest tenth of bones moves far less than the trunk
    thin = np.argsort(bm.branch_radii(truth.parents, truth.radius)[1])[: max(1, B // 10)]
    assert np.abs(along[thin]).max() < 0.5 * np.abs(along[0]).max()


def _ring_uv(tree, rest, forks):
    """The rings' ``(u0 (B, K), v (B, K))`` as the relief mesh is built (the same pipe radii)."""
    from tree_from_video.core.detail.forks import pipe_heads
    r_head, r_tail = bm.branch_radii(tree.parents, tree.radius)
    delta = pipe_exponent(tree)
    r_head = pipe_heads(tree.parents, r_head, r_tail, delta)
    g = bm.tube_arrays(tree.nodes3d[0], tree.parents, rest, r_head, r_tail, RELIEF_SIDES, curliness=0.3,
                       bark="rough", rings=RELIEF_RINGS, forks=forks, pipe_exponent=delta)
    return g["u0"], g["v"]


def test_photo_tiles_repeat_round_the_tube(truth):
    """A photo's height with ``repeats`` = 4: the trunk's moves repeat every quarter of the ring."""
    rest = bones.rest_frames(truth.parents, truth.nodes3d[0])
    rng = np.random.default_rng(5)
    height = rng.random((64, 64)).astype(np.float32)
    p = bm.MeshParams(curliness=0.0, bark="none", relief_cm=1.0)
    m3 = branch_arrays(truth, rest, p, relief_map=(height, 4))
    m1 = branch_arrays(truth, rest, p, relief_map=(height, 1))
    flat = branch_arrays(truth, rest, bm.MeshParams(curliness=0.0, bark="none", sides=RELIEF_SIDES, rings=RELIEF_RINGS))
    K, S = RELIEF_RINGS, RELIEF_SIDES
    d3 = np.linalg.norm((m3.co - flat.co).reshape(-1, K, S, 3)[0], axis=-1)
    d1 = np.linalg.norm((m1.co - flat.co).reshape(-1, K, S, 3)[0], axis=-1)
    np.testing.assert_allclose(d3[:, : S // 4], d3[:, S // 4: S // 2], atol=1e-6)
    assert np.abs(d1[:, : S // 4] - d1[:, S // 4: S // 2]).max() > 1e-4       # once round: no repeat


def test_relief_setting_is_recorded_and_lods_keep_none(truth):
    """``meta.mesh.relief_cm`` is read back by the look; LOD1 is built without relief (fewer sides
    than the relief needs) and LOD0 with it."""
    t = broad_tree(2)
    t.meta["mesh"] = {"curliness": 0.3, "bark": "rough", "seed": 0, "forks": "joined", "relief_cm": 1.5}
    a = tree_asset(t, leaves=False, lods=2)
    assert a.look.mesh.relief_cm == 1.5
    assert len(a.branches.co) == len(bones.bone_edges(t.parents)) * RELIEF_RINGS * RELIEF_SIDES
    assert a.lods[1].branches is not None and len(a.lods[1].branches.co) < len(a.branches.co) / 4
    plain = tree_asset(t, leaves=False, relief_cm=0.0)
    assert len(plain.branches.co) < len(a.branches.co) / 4
