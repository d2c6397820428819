"""A wide trunk's trace is straightened across itself (issue 35; the real cedar photo: a trunk
40 px wide traced from edge to edge of it, its foot a quarter of its width right of the middle,
and a second path up its shaded edge drawn as a stub along it). Hand cases of
``stems.local_line``, ``stems.ridge_middles`` and ``stems.straighten_stem``."""
import numpy as np

from tree_from_video.core.reconstruct.stems import local_line, main_stem, ridge_middles, straighten_stem


def test_local_line_is_exact_on_a_line_and_follows_a_bend():
    y = np.linspace(0.0, 300.0, 31)
    x = 100.0 + 0.2 * y
    assert np.allclose(local_line(y, x, np.array([-50.0, 150.0, 400.0]), 40.0), 100.0 + 0.2 * np.array([-50, 150, 400]))
    # a bend over many σ: each query keeps to its own part of it
    xb = np.where(y < 150, 100.0, 100.0 + 0.5 * (y - 150))
    fit = local_line(y, xb, np.array([20.0, 290.0]), 15.0)
    assert abs(fit[0] - 100.0) < 0.5 and abs(fit[1] - 170.0) < 0.5, fit


def test_ridge_middles_take_the_ridge_column_near_the_polyline():
    ridge = np.zeros((100, 60), np.float32)
    ridge[:, 30] = 1.0                                # the trunk's middle
    ridge[:, 5] = 2.0                                 # a stronger ridge, farther than half a width
    xy = np.array([[36.0, 90.0], [26.0, 10.0]])       # a trace leaning across the trunk
    y, x = ridge_middles(ridge, xy, 20.0)
    assert y[0] == 10 and y[-1] == 90 and len(y) == 81
    assert np.all(x == 30)


def trunk_tree():
    """A stem up a trunk 40 px wide at x = 100 (rows 400 → 200 bare, then a crown, the trunk seen
    on up to row 150 and the stem bending off above), traced zig-zag across it, with a stub up its
    left edge and a real limb leaving it to the right.
    Returns ``(parents, pos, mask, ridge)``."""
    stem_y = np.arange(400.0, 99.0, -25.0)                                  # 13 nodes, root at 400
    stem_x = 100.0 + np.where(np.arange(len(stem_y)) % 2 == 1, 12.0, -4.0)   # edge to edge
    stem_x[stem_y < 200] = [104.0, 97.0, 130.0, 145.0]   # on up the trunk through the crown, then its bend
    pos = [np.array([x, y]) for x, y in zip(stem_x, stem_y)]
    parents = [-1] + list(range(len(stem_y) - 1))
    stub = [(84.0, 340.0), (83.0, 310.0)]                                     # off node 2 (y 350)
    parents += [2, len(pos)]
    pos += [np.array(p) for p in stub]
    limb = [(130.0, 290.0), (170.0, 270.0)]                                   # off node 4 (y 300)
    parents += [4, len(pos)]
    pos += [np.array(p) for p in limb]
    mask = np.zeros((420, 300), bool)
    mask[200:401, 75:126] = True                      # the outline's stem: 50 px
    mask[60:200, 20:280] = True                       # the crown: 260 px
    ridge = np.zeros((420, 300), np.float32)
    ridge[200:401, 100] = 1.0
    return np.array(parents), np.array(pos), mask, ridge


def test_a_zigzag_trunk_is_straightened_and_a_stub_on_its_bark_dropped():
    parents, pos, mask, ridge = trunk_tree()
    p2, q = straighten_stem(parents, pos, 40.0, mask, ridge)
    assert len(p2) == len(parents) - 2                                       # the stub, and only it
    assert parents[0] == -1 and p2[0] == -1
    trunk = q[:11]                                                           # rows 400 … 150
    assert np.abs(trunk[:, 0] - 100.0).max() < 1.0, trunk
    assert np.allclose(q[11:13], pos[11:13])                                 # the crown's bend stays
    # the limb is kept, hanging from the same stem node at its own place
    kept = q[-2:]
    assert np.allclose(kept, pos[-2:]) and p2[-2] == 4 and p2[-1] == len(p2) - 2
    # without the ridge the line goes through the nodes: straight, off by their mean offset
    p3, r = straighten_stem(parents, pos, 40.0, mask)
    lean = np.degrees(np.arctan2(np.abs(np.diff(r[:9, 0])), np.abs(np.diff(r[:9, 1]))))
    assert lean.max() < 2.0 and np.abs(r[:9, 0] - 100.0).max() < 6.0


def test_no_trunk_width_no_change():
    parents, pos, mask, ridge = trunk_tree()
    p2, q = straighten_stem(parents, pos, float("nan"), mask, ridge)
    assert np.array_equal(p2, parents) and np.array_equal(q, pos)
    assert list(main_stem(parents, pos)) == list(range(11))       # up to the bend past 45°


def test_subtree_sizes_by_hand():
    from tree_from_video.core.topology import subtree_sizes
    #       0
    #      / \
    #     1   2
    #    / \    \
    #   3   4    5 - 6
    parents = np.array([-1, 0, 0, 1, 1, 2, 5])
    assert subtree_sizes(parents).tolist() == [7, 3, 3, 1, 1, 2, 1]
    assert subtree_sizes(np.array([-1])).tolist() == [1]


def test_without_nodes_reindexes_the_kept_tree():
    from tree_from_video.core.topology import without_nodes
    parents = np.array([-1, 0, 0, 1, 1, 2, 5])
    keep, par, index = without_nodes(parents, np.array([0, 1, 0, 1, 1, 0, 0], bool))   # node 1's subtree
    assert keep.tolist() == [0, 2, 5, 6] and par.tolist() == [-1, 0, 1, 2]
    assert index.tolist() == [0, -1, 1, -1, -1, 2, 3]
