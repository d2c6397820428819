"""Bark from photos of bark (issue 36, core/detail/bark_photo.py): a seamless tile, relief and
normals of the right scale, moss and lichen found by colour and their cover under the controls;
bad photos refused with one line. The photos are synthetic close-ups (tests/bark_photos.py) with a
light gradient, noise and JPEG; seeds 3 and 11 were never looked at while writing the module."""
import json

import cv2
import numpy as np
import pytest
from bark_photos import bark_pair, bark_photo

from tree_from_video.core.detail import bark_photo as bp
from tree_from_video.core.errors import InputError

pytestmark = [pytest.mark.bpy53]

SMALL = bp.BarkPhotoParams(size=256, step=48, overlap=12, candidates=120)


def test_min_cut_follows_the_cheapest_seam_by_hand():
    err = np.full((6, 5), 9.0)
    cols = [1, 2, 2, 3, 4, 3]                      # a cheap path moving at most one column a row
    err[np.arange(6), cols] = 0.0
    assert bp.min_cut(err).tolist() == cols
    err[2, 3] = -1.0                               # cheaper, but two columns from row 1's: not reachable
    err[2, 2] = 0.0
    assert bp.min_cut(err).tolist()[1:4] == [2, 3, 3] or bp.min_cut(err).tolist()[1:4] == [2, 2, 3]


@pytest.mark.parametrize("seed", [3, 11])
def test_the_tile_repeats_without_a_seam(seed):
    photo, _, _ = bark_photo(seed)
    maps = bp.bark_maps([photo], SMALL)
    tile = cv2.cvtColor(maps.textures.albedo, cv2.COLOR_RGB2BGR)
    assert tile.shape == (240, 240, 3)                                # 5 steps of 48
    seam, own = bp.seam_difference(tile), maps.neighbour_diff
    naive = bp.seam_difference(photo[:240, :240])                     # a crop of the photo, repeated
    median = bp.neighbour_difference(photo, np.median)
    print(f"\nseed {seed}: seam {seam:.1f}, the photo's own neighbour difference {own:.1f} (median {median:.1f}), "
          f"the tile's {bp.neighbour_difference(tile):.1f}, a crop's seam {naive:.1f}")
    assert seam <= 1.5 * own
    assert naive > 1.5 * own                                          # what the quilting mends
    # the light's gradient is gone: the ramp fitted to the photo's luminance, before and after
    def ramp(im):
        lum = im.astype(np.float64).mean(-1)
        y, x = np.mgrid[0:lum.shape[0], 0:lum.shape[1]]
        A = np.stack([x.ravel() / lum.shape[1], y.ravel() / lum.shape[0], np.ones(lum.size)], 1)
        coef = np.linalg.lstsq(A, lum.ravel(), rcond=None)[0]
        return float(np.hypot(*coef[:2]) / lum.mean())          # brightness change across the photo
    raw, even = ramp(photo), ramp(bp.even_light(photo))
    quads = [tile[i:i + 120, j:j + 120].astype(np.float64).mean() for i in (0, 120) for j in (0, 120)]
    spread = float(np.std(quads) / np.mean(quads))
    print(f"light across the photo {raw:.3f} -> {even:.3f}; the tile's quarters' brightness spread {spread:.3f}")
    assert even < 0.25 * raw and spread < 0.05
    # the relief stays under its colour: crevices (low height) are darker
    h, lum = maps.textures.height, tile.astype(np.float32).mean(-1)
    assert lum[h < 0.3].mean() < 0.8 * lum[h > 0.7].mean()


def test_the_normal_map_has_the_relief_it_is_asked_for_by_hand():
    """A height ramp rising by 1 over 64 texels on a 64-texel tile of 50 cm, 1 cm deep: the slope
    s ∂h/∂u = (1 / 50 · 64) · (1 / 64) = 0.02, so n = (−0.02, 0, 1) normalized inside the ramp."""
    S = 64
    h = np.tile(np.arange(S, dtype=np.float32) / S, (S, 1))
    n = bp.normal_map(h, 1.0 / 50.0 * S).astype(np.float64) / 127.5 - 1.0
    want = np.array([-0.02, 0.0, 1.0]) / np.hypot(0.02, 1.0)
    assert np.abs(n[:, 2:-2] - want).max() < 1.0 / 127.5
    # and bark_maps passes relief_cm / scale_cm · S: twice the relief, twice the tilt
    photo, _, _ = bark_photo(3)
    flat = bp.bark_maps([photo], bp.BarkPhotoParams(**{**SMALL.__dict__, "relief_cm": 0.5}))
    deep = bp.bark_maps([photo], bp.BarkPhotoParams(**{**SMALL.__dict__, "relief_cm": 1.0}))
    tilt = [np.abs(m.textures.normal[..., 0].astype(np.float64) - 127.5).mean() for m in (flat, deep)]
    assert tilt[1] == pytest.approx(2 * tilt[0], rel=0.15)


def test_moss_and_lichen_found_by_colour():
    photo, moss, lichen = bark_photo(11)
    m, li = bp.moss_lichen(photo)
    iou = [(a & b).sum() / (a | b).sum() for a, b in ((m, moss), (li, lichen))]
    print(f"\nmoss IoU {iou[0]:.2f}, lichen IoU {iou[1]:.2f}")
    assert iou[0] >= 0.8 and iou[1] >= 0.6
    assert not bp.moss_lichen(bark_photo(11, moss_share=0.0, lichen_share=0.0)[0])[1].any()   # lit bark is no lichen


def test_the_controls_scale_the_cover():
    photo, _, _ = bark_photo(3, moss_share=0.1)
    covers = {}
    for k in (0.0, 0.5, 1.0, 2.0):
        maps = bp.bark_maps([photo], bp.BarkPhotoParams(**{**SMALL.__dict__, "moss": k}))
        seen, _ = bp.moss_lichen(cv2.cvtColor(maps.textures.albedo, cv2.COLOR_RGB2BGR))   # measured by colour
        covers[k] = (maps.moss[1], float(seen.mean()))
    print("\ncover (kept, seen by colour) per Moss:", {k: tuple(round(c, 3) for c in v) for k, v in covers.items()})
    one = covers[1.0][1]
    assert 0.05 < one < 0.2
    assert covers[0.0][1] < 0.1 * one
    assert covers[0.5][1] == pytest.approx(0.5 * one, rel=0.25)
    assert covers[2.0][1] == pytest.approx(2.0 * one, rel=0.2)
    # the spread moss lies in crevices first
    maps = bp.bark_maps([photo], bp.BarkPhotoParams(**{**SMALL.__dict__, "moss": 2.0}))
    plain = bp.bark_maps([photo], SMALL)
    grown = maps.textures.height[(maps.roughness == np.float32(0.9)) & ~(plain.roughness == np.float32(0.9))]
    assert grown.mean() < plain.textures.height.mean()


def test_the_same_seed_gives_the_same_tile_and_bad_photos_are_one_line(tmp_path):
    photo, _, _ = bark_photo(3)
    a, b = (bp.bark_maps([photo], SMALL).textures.albedo for _ in range(2))
    assert np.array_equal(a, b)
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), photo[:100, :100])
    flat = tmp_path / "flat.png"
    cv2.imwrite(str(flat), np.full((300, 300, 3), 90, np.uint8))
    junk = tmp_path / "junk.jpg"
    junk.write_bytes(b"not an image")
    for path, needle in ((small, "at least 160 px"), (flat, "flat colour"), (junk, "not a readable image")):
        with pytest.raises(InputError, match=needle) as exc:
            bp.read_bark_photo(str(path))
        assert "\n" not in str(exc.value)


def test_the_uv_square_puts_the_moss_on_the_branches_upper_side():
    """uv_square moves the tile's moss to the columns of u ≡ U_UP (the tubes' upper side,
    branch_mesh.up_offsets): the same cover, ≥ 5× as dense in the upper quarter as in the lower."""
    from tree_from_video.core.detail.branch_mesh import U_UP
    photo, _, _ = bark_photo(9, moss_share=0.1)
    # by hand: four columns at u = ⅛, ⅜, ⅝, ⅞ around U_UP = ½: ½ (1 + cos 2π(u − ½))
    assert U_UP == 0.5
    np.testing.assert_allclose(bp.up_weight(4), [0.5 - 0.5 ** 1.5, 0.5 + 0.5 ** 1.5, 0.5 + 0.5 ** 1.5, 0.5 - 0.5 ** 1.5])
    for k in (0.0, 1.0, 2.0):
        maps = bp.bark_maps([photo], bp.BarkPhotoParams(**{**SMALL.__dict__, "moss": k}))
        albedo, _, rough, repeats = bp.uv_square(maps, 0.3)
        seen, _ = bp.moss_lichen(cv2.cvtColor(albedo, cv2.COLOR_RGB2BGR))     # measured by colour
        up = bp.up_weight(seen.shape[1])
        top, bottom = seen[:, up > 0.85].mean(), seen[:, up < 0.15].mean()
        print(f"\nMoss {k}: {repeats}×{repeats} tiles, cover {100 * seen.mean():.1f} % (tile {100 * maps.moss[1]:.1f} %), "
              f"upper side {100 * top:.1f} %, underside {100 * bottom:.1f} %")
        if k == 0.0:
            assert seen.mean() < 0.005
            continue
        assert seen.mean() == pytest.approx(maps.moss[1], rel=0.25)
        assert top >= 5.0 * bottom and top > 2.0 * seen.mean()
        assert rough[seen].mean() > 0.88                                          # moss's roughness where it went


def _high_pass(h, sigma):
    return h - cv2.GaussianBlur(h.astype(np.float32), (0, 0), sigma)


@pytest.mark.parametrize("seed,move", [(31, (4.0, 1.2, -0.5)), (32, (-3.0, -2.0, -4.0)), (33, (1.5, 0.0, 0.0))])
def test_two_photos_of_the_same_bark_give_its_height_by_parallax(seed, move):
    """Two hand-held shots of one patch of bark (tests/bark_photos.bark_pair: colour blotches of its
    own, a grazing light), the second moved by ``move`` cm: where the two see the same bark (≥ 60 %
    of each), each photo's height correlates ≥ 0.8 with the true relief (high-passed as the method
    does), where its shading gives ≤ 0.2."""
    a, b, ha, hb = bark_pair(seed, move=move)
    sigma = (SMALL.step + SMALL.overlap) / 2.0
    heights, said = bp.photo_heights([a, b], sigma)
    shading = [bp.shading_height(bp.even_light(img), sigma) for img in (a, b)]
    inner = (slice(24, -24), slice(24, -24))
    for k, truth in enumerate((ha, hb)):
        both = (heights[k] != shading[k])[inner]                       # where the height came from parallax
        t = _high_pass(truth, sigma)[inner][both]
        got = np.corrcoef(heights[k][inner][both], t)[0, 1]
        shade = np.corrcoef(shading[k][inner][both], t)[0, 1]
        print(f"\nseed {seed}, photo {k + 1} ({said[k]}): height vs the true relief {got:.3f} on "
              f"{100 * both.mean():.0f} % of it, shading's {shade:.3f}")
        assert said[k].startswith(f"stereo with photo {2 - k}") and both.mean() >= 0.6
        assert got >= 0.8 and shade <= 0.2


def test_photos_of_different_bark_keep_their_shading_height():
    a, b = bark_pair(34)[0], bark_pair(35)[0]
    sigma = (SMALL.step + SMALL.overlap) / 2.0
    heights, said = bp.photo_heights([a, b], sigma)
    assert said == ("shading", "shading")
    np.testing.assert_array_equal(heights[1], bp.shading_height(bp.even_light(b), sigma))


def test_bark_json_says_where_each_photos_height_came_from(tmp_path):
    a, b, _, _ = bark_pair(36, move=(-2.5, 1.0, 0.0))
    c = bark_photo(36)[0]                                    # a close-up of another bark
    maps = bp.bark_maps([a, b, c], SMALL)
    assert [s.split(":")[0] for s in maps.height_from] == ["stereo with photo 2", "stereo with photo 1", "shading"]
    bp.write_bark_files(maps, str(tmp_path), ["a.jpg", "b.jpg", "c.jpg"])
    assert json.loads((tmp_path / "bark.json").read_text())["height_from"] == list(maps.height_from)


def test_a_folder_of_bark_photos_is_its_images(tmp_path):
    for name in ("b.jpg", "a.PNG", "notes.txt"):
        (tmp_path / name).write_bytes(b"x")
    assert bp.bark_photo_files(str(tmp_path)) == [str(tmp_path / "a.PNG"), str(tmp_path / "b.jpg")]
    assert bp.bark_photo_files(str(tmp_path / "b.jpg")) == [str(tmp_path / "b.jpg")]
    (tmp_path / "empty").mkdir()
    for bad, needle in ((tmp_path / "empty", "holds no photo"), (tmp_path / "gone", "does not exist")):
        with pytest.raises(InputError, match=needle):
            bp.bark_photo_files(str(bad))
