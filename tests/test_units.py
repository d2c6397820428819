"""Unit tests of the core's building blocks on cases small enough to check by hand."""
import numpy as np
import pytest
import scipy.sparse as sp
from textures import shifted, texture

from tree_from_video.core.reconstruct import hierarchy, skeleton2d
from tree_from_video.core.reconstruct import tracks as trk

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]


def _two_blobs(n=60, seed=0):
    rng = np.random.default_rng(seed)
    a = rng.normal([0, 0], 1.0, (n, 2))
    b = rng.normal([12, 0], 1.0, (n, 2))
    return np.vstack([a, b])


def _gauss_knn_affinity(p, k=8):
    from scipy.spatial import cKDTree
    d, idx = cKDTree(p).query(p, k=k + 1)
    i = np.repeat(np.arange(len(p)), k)
    W = sp.coo_matrix((np.exp(-d[:, 1:].ravel() ** 2 / 2.0), (i, idx[:, 1:].ravel())), shape=(len(p),) * 2).tocsr()
    return W.maximum(W.T).tocsr()


def test_ncut_splits_two_obvious_clusters():
    p = _two_blobs()
    W = _gauss_knn_affinity(p, k=20)
    # join the blobs weakly so the graph is connected and the eigenvector decides
    W = W + sp.coo_matrix(([1e-3, 1e-3], ([0, 60], [60, 0])), shape=W.shape).tocsr()
    side = hierarchy.split_cluster(W, 4)
    truth = np.arange(len(p)) < 60
    agree = max((side == truth).mean(), (side != truth).mean())
    assert agree == 1.0


def test_fiedler_matches_dense_generalized_eigenproblem():
    from scipy.linalg import eigh
    rng = np.random.default_rng(3)
    p = rng.uniform(0, 10, (40, 2))
    W = _gauss_knn_affinity(p, k=10)
    D = np.diag(np.asarray(W.sum(1)).ravel())
    vals, vecs = eigh(D - W.toarray(), D)         # (D − W) y = λ D y, dense reference
    ref = vecs[:, 1]
    y = hierarchy.fiedler_vector(W)
    cos = abs(ref @ D @ y) / np.sqrt((ref @ D @ ref) * (y @ D @ y))
    assert cos > 0.9999


def test_ncut_value_matches_definition():
    p = _two_blobs(20)
    W = _gauss_knn_affinity(p, k=6)
    y = hierarchy.fiedler_vector(W)
    side, value = hierarchy.best_ncut_split(W, y, 1)
    Wd = W.toarray()
    cut = Wd[side][:, ~side].sum()
    ref = cut / Wd[side].sum() + cut / Wd[~side].sum()
    assert value == pytest.approx(ref, rel=1e-9)


def test_fold_hand_computed():
    # chain root(0,0) -> a(10,0) -> b(20,0) -> c(30, 0); levels 0..3; fold stops at level 2
    pos = np.array([[0, 0], [10, 0], [20, 0], [30, 0]], float)
    parents = np.array([-1, 0, 1, 2])
    level = np.array([0, 1, 2, 3])
    out = skeleton2d.fold(pos, parents, level, alpha=0.4)
    # a: 10 + 0.4*(0-10) = 6; b: 20 + 0.4*(6-20) = 14.4; c (last level) unchanged
    assert out[:, 0] == pytest.approx([0, 6, 14.4, 30])


def test_binarize_node_with_four_children():
    pos = np.array([[0, 0], [0, -10], [-5, -12], [5, -13], [0, -20]], float)
    parents = np.array([-1, 0, 0, 0, 0])
    par, p2 = skeleton2d.binarize(parents, pos)
    counts = np.bincount(par[par >= 0], minlength=len(par))
    assert counts.max() <= 2
    assert len(par) == 5 + 2            # a node with k children needs k − 2 extra nodes
    assert np.array_equal(p2[:5], pos)  # original nodes keep index and place
    # every original child still descends from the root
    for c in range(1, 5):
        u = c
        while par[u] != -1:
            u = par[u]
        assert u == 0


def test_tracker_recovers_known_subpixel_shift():
    img = texture()
    moved = shifted(img, 2.3, -1.6)
    mask = np.zeros(img.shape, bool)
    mask[40:200, 60:260] = True
    pts = trk.detect_corners(img, mask, trk.TrackParams())
    new, ok = trk.lk_forward_backward(img, moved, pts, 1.0)
    err = np.abs(np.median(new[ok] - pts[ok], axis=0) - [2.3, -1.6])
    assert ok.mean() > 0.9 and err.max() < 0.1


def test_camera_motion_removal_recovers_known_shift():
    img = texture(seed=4)
    moved = shifted(img, -1.5, 2.0)
    mask = np.zeros(img.shape, bool)
    mask[80:160, 120:200] = True
    cam = trk.CameraEstimator(img, mask, trk.TrackParams())
    m = cam.update(img, moved)
    # a point at p in the moved image is at p + (1.5, -2.0) in frame 1
    assert m[:, 2] == pytest.approx([1.5, -2.0], abs=0.1)
    assert m[:, :2] == pytest.approx(np.eye(2), abs=0.01)


def test_nan_median_rows_matches_numpy():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(50, 7, 2))
    a[rng.random(a.shape) < 0.3] = np.nan
    a[3] = np.nan
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        ref = np.nanmedian(a, axis=1)
    assert np.allclose(trk.nan_median_rows(a), ref, equal_nan=True)


def test_prefetch_transforms_in_the_reader_thread_in_order_and_passes_errors():
    import threading

    from tree_from_video.core.reconstruct.video import prefetch
    where = []

    def square(x):
        where.append(threading.current_thread().name)
        return x * x
    assert list(prefetch(iter(range(10)), transform=square)) == [x * x for x in range(10)]
    assert set(where) == {"tree_from_video-decode"}

    def broken(x):
        if x == 3:
            raise ValueError("bad frame 3")
        return x
    got = []
    with pytest.raises(ValueError, match="bad frame 3"):
        for x in prefetch(iter(range(10)), transform=broken):
            got.append(x)
    assert got == [0, 1, 2]


def test_prepared_frames_track_like_plain_ones():
    """Tracking frames whose images were prepared elsewhere (as the pipeline does in the decoding
    thread) gives the same tracks as feeding the frames themselves."""
    from tree_from_video.core.outline import Outline
    img = texture(seed=2)
    mask = np.zeros(img.shape, bool)
    mask[40:200, 60:260] = True
    frames = [shifted(img, 0.4 * k, -0.3 * k) for k in range(1, 6)]
    runs = []
    for prepared in (False, True):
        tr = trk.Tracker(img, Outline(np.zeros((0, 2), np.float32), mask), 24.0, params=trk.TrackParams(redetect_every=2))
        for f in frames:
            if prepared:
                tr.feed(None, prepared=tr.prepare(f))
            else:
                tr.feed(f)
        runs.append(tr.result())
    assert np.array_equal(runs[0].points, runs[1].points) and np.array_equal(runs[0].valid, runs[1].valid)
    assert runs[1].valid[-1].mean() > 0.9
