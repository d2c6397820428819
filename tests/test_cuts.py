"""Tree-cuts (issue 36 part 3, seed 001's editing operator): a part of a tree saved as a cut
(.npz + JSON header) and placed in a generated tree, which grows the rest around it. A placed cut
appears unchanged: its bone lengths and angles (with each other and with the branch it hangs
from) within 1 %, its radii as saved; the tree's branches keep clear of it; the branch carrying
it thickens by the pipe model."""

import json
import math

import numpy as np
import pytest

from tree_from_video.core.asset.cut_mesh import with_mesh
from tree_from_video.core.errors import InputError
from tree_from_video.core.generate import cuts, envelopes, growth
from tree_from_video.core.generate.batch import load_species_spec
from tree_from_video.core.rotations import quat_to_matrix, rodrigues, swing
from tree_from_video.core.topology import subtree
from tree_from_video.core.tree3d import Tree3D, pipe_radii
from tree_from_video.core.tree_cut import bone_lengths, cut_from_tree, load_cut, save_cut

from trees import broad_tree

pytestmark = [pytest.mark.bpy53]


def _hand_tree() -> Tree3D:
    """0 → 1 (trunk, 2 m up) → 2 (on up), 1 → 3 → 4 (a side branch at 45° then on), 3 → 5."""
    pos = np.array([[0, 0, 0], [0, 0, 2], [0, 0, 4], [1, 0, 3], [2, 0, 3.5], [1.5, 0.5, 3.8]], float)
    parents = np.array([-1, 0, 1, 1, 3, 3], np.int32)
    return Tree3D(parents, pos[None].astype(np.float32), np.array([.2, .15, .1, .08, .04, .03], np.float32),
                  np.zeros(6, np.int32), 24.0, "hand")


def bone_angles(parents: np.ndarray, pos: np.ndarray, into_root: np.ndarray | None = None) -> np.ndarray:
    """``(N,)`` radians between the bone into each node and its parent's bone (nan for a root;
    for a child of a root, the angle with ``into_root`` when given, else nan)."""
    p = np.asarray(parents)
    out = np.full(len(p), np.nan)
    d = np.zeros((len(p), 3))
    has = p >= 0
    v = pos[has] - pos[p[has]]
    d[has] = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
    gp = np.where(has, p[np.maximum(p, 0)], -1)
    inner = has & (gp >= 0)
    out[inner] = np.arccos(np.clip(np.sum(d[inner] * d[p[inner]], axis=1), -1.0, 1.0))
    if into_root is not None:
        first = has & (gp < 0)
        u = np.asarray(into_root, np.float64)
        out[first] = np.arccos(np.clip(d[first] @ (u / np.linalg.norm(u)), -1.0, 1.0))
    return out


# ----------------------------------------------------------------------------- by hand

def test_the_placing_rotations_by_hand():
    """Placement turns a cut by ``rodrigues(ψ d) · quat_to_matrix(swing(u, d))`` (core.rotations)."""
    R = quat_to_matrix(swing(np.array([1.0, 0, 0]), np.array([0, 0, 1.0])))
    assert np.allclose(R @ [1, 0, 0], [0, 0, 1]) and np.allclose(R @ R.T, np.eye(3))
    assert np.allclose(R @ [0, 1, 0], [0, 1, 0])                  # the shortest turn keeps the normal
    opp = quat_to_matrix(swing(np.array([0, 0, 1.0]), np.array([0, 0, -1.0])))
    assert np.allclose(opp @ [0, 0, 1], [0, 0, -1]) and np.isclose(np.linalg.det(opp), 1.0)
    Rz = rodrigues(np.array([[0, 0, math.pi / 2]]))[0]
    assert np.allclose(Rz @ [1, 0, 0], [0, 1, 0])


def test_pipe_radii_keep_fixed_nodes_and_carry_them():
    parents = np.array([-1, 0, 1, 1, 3])             # 0-1, fork at 1 into 2 (tip) and 3-4
    free = pipe_radii(parents, 0.1, 2.0)
    fixed = np.full(5, np.nan)
    fixed[[3, 4]] = [0.3, 0.25]                      # a cut's nodes, thicker than the tips
    r = pipe_radii(parents, 0.1, 2.0, fixed)
    assert np.allclose(r[[3, 4]], [0.3, 0.25])
    assert np.isclose(r[1], math.sqrt(0.1 ** 2 + 0.3 ** 2)) and np.isclose(r[0], r[1])   # r^2 = Σ r_c^2
    assert np.isclose(r[2], free[2])


def test_cut_from_a_tree_by_hand():
    t = _hand_tree()
    c = cut_from_tree(t, ["B003"])                   # the side branch with all it carries
    assert list(c.source_nodes) == [1, 3, 4, 5] and list(c.parents) == [-1, 0, 1, 1]
    assert np.allclose(c.rest[0], 0) and np.allclose(c.rest[1], [1, 0, 1])
    assert np.allclose(c.parent_dir, [0, 0, 1]) and np.allclose(c.radius, [.15, .08, .04, .03])
    assert list(cut_from_tree(t, ["B003"], whole_branch=False).source_nodes) == [1, 3]
    assert list(cut_from_tree(t, [2, 3]).source_nodes) == [1, 2, 3, 4, 5]      # siblings: one base
    with pytest.raises(InputError, match="2 separate pieces"):
        cut_from_tree(t, ["B002", "B004"], whole_branch=False)
    with pytest.raises(InputError, match="branch bones"):
        cut_from_tree(t, ["Leaf_001"])
    with pytest.raises(InputError, match="not in this tree"):
        cut_from_tree(t, ["B009"])


def test_cut_file_round_trip_and_refusals(tmp_path):
    src = broad_tree(frames=2)
    c = with_mesh(src, cut_from_tree(src, ["B040"]))
    path = tmp_path / "limb.npz"
    save_cut(path, c)
    back = load_cut(path)
    for k in ("parents", "rest", "radius", "parent_dir", "source_nodes"):
        assert np.array_equal(getattr(back, k), getattr(c, k)), k
    assert np.array_equal(back.mesh.co, c.mesh.co) and np.array_equal(back.mesh.loop_vert, c.mesh.loop_vert)
    with np.load(path) as z:
        head = json.loads(str(z["meta_json"]))
    assert head["format"] == "tree_from_video.cut" and head["bones"] == c.n_bones
    with pytest.raises(InputError, match="exists"):
        save_cut(path, c)
    save_cut(path, c, overwrite=True)
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(InputError, match="not a Tree from Video cut"):
        load_cut(tmp_path / "other.npz")
    with pytest.raises(InputError, match="does not exist"):
        load_cut(tmp_path / "none.npz")


def test_cut_mesh_is_the_sources_around_the_cut_bones():
    src = broad_tree(frames=2)
    c = with_mesh(src, cut_from_tree(src, ["B040"]))
    m = c.mesh
    assert len(m.co) > 8 * c.n_bones and (m.node >= 1).all()
    # every vertex lies near its bone's segment: within 3 radii of it (curl and bark included)
    P = c.rest
    a, b = P[c.parents[m.node]], P[m.node]
    t = np.clip(np.sum((m.co - a) * (b - a), 1) / np.maximum(np.sum((b - a) ** 2, 1), 1e-12), 0, 1)
    d = np.linalg.norm(m.co - (a + t[:, None] * (b - a)), axis=1)
    assert np.all(d <= 3.0 * np.maximum(c.radius[c.parents[m.node]], c.radius[m.node]) + 1e-3)
    assert m.loop_start[-1] + m.loop_total[-1] == len(m.loop_vert) and m.loop_vert.max() < len(m.co)


@pytest.mark.parametrize("text,at", [("a.npz", None), ("dir/a b.npz@0.5,-1,4", (0.5, -1.0, 4.0))])
def test_cut_spec(text, at):
    spec = cuts.parse_cut_spec(text)
    assert spec.at == at and spec.path == text.split("@")[0]


def test_cut_spec_refused():
    with pytest.raises(InputError, match="X,Y,Z"):
        cuts.parse_cut_spec("a.npz@1,2")


# ----------------------------------------------------------------------------- placed in new trees

@pytest.fixture(scope="module")
def broad():
    return load_species_spec("broad")[0]


@pytest.fixture(scope="module")
def limb(tmp_path_factory):
    """A limb of the sample's true tree (a reconstruction's size and shape), saved."""
    src = broad_tree(frames=2)
    sizes = np.array([subtree(src.parents, [n]).sum() for n in range(src.n_nodes)])
    node = int(np.flatnonzero((sizes >= 12) & (sizes <= 30) & (src.parents > 0))[0])
    c = cut_from_tree(src, [node])
    path = tmp_path_factory.mktemp("cuts") / "limb.npz"
    save_cut(path, c)
    return str(path), c


def _grow(model, path, at=None, seed=23, wind=0.0, twigs=0, nodes=200):
    env = envelopes.envelope_from_any("circle", 10.0)
    p = growth.GrowParams(seed=seed, n_frames=3 if wind == 0 else 24, wind=wind, twig_depth=twigs,
                          leaf_density=0.0, node_budget=nodes, cuts=(cuts.CutSpec(path, at),))
    return growth.grow_tree(model, env, p)


def _placed_nodes(tree) -> tuple[np.ndarray, dict]:
    info = tree.meta["cuts"][0]
    return np.arange(info["first_node"], info["first_node"] + info["bones"]), info


def _check_unchanged(tree, cut, nodes, info, frame=0):
    pos = tree.nodes3d[frame].astype(np.float64)
    sub = np.concatenate([[info["base_node"]], nodes])
    local = pos[sub]
    L_new = bone_lengths(cut.parents, local)[1:]
    assert np.abs(L_new / cut.bone_lengths() - 1).max() < 0.01
    base_parent = tree.parents[info["base_node"]]
    into = pos[info["base_node"]] - (pos[base_parent] if base_parent >= 0 else pos[info["base_node"]] - [0, 0, 1])
    a_new = bone_angles(cut.parents, local, into)[1:]
    a_old = bone_angles(cut.parents, cut.rest, cut.parent_dir)[1:]
    assert np.abs(a_new - a_old).max() <= 0.01 * np.abs(a_old).max()
    assert np.abs(a_new - a_old).max() < np.radians(0.5)


@pytest.mark.parametrize("seed", [23, 41])
def test_a_cut_placed_where_it_fits_is_unchanged(broad, limb, seed):
    path, cut = limb
    tree = _grow(broad, path, seed=seed)
    nodes, info = _placed_nodes(tree)
    assert info["placed"] == "fit" and info["bones"] == cut.n_bones and info["inside_share"] >= 0.9
    _check_unchanged(tree, cut, nodes, info)
    assert np.allclose(tree.radius[nodes], cut.radius[1:], rtol=1e-6)
    assert np.array_equal(tree.parents[nodes] - info["first_node"] + 1,
                          np.where(cut.parents[1:] == 0, tree.parents[nodes] - info["first_node"] + 1, cut.parents[1:]))
    assert (tree.parents[nodes[cut.parents[1:] == 0]] == info["base_node"]).all()
    # the branch it hangs from carries it (pipe model): at least as thick as the cut's first bone
    first = nodes[cut.parents[1:] == 0]
    assert tree.radius[info["base_node"]] >= tree.radius[first].max() - 1e-6
    # the tree's own branches keep the clearance: none of theirs within it of a cut bone
    pos = tree.nodes3d[0].astype(np.float64)
    own = np.setdiff1d(np.flatnonzero(tree.parents >= 0), nodes)
    anc = cuts.ancestors(tree.parents, info["base_node"])
    own = own[~anc[own] & (tree.parents[own] != info["base_node"])]
    d = cuts.segment_distance(pos[own], pos[tree.parents[nodes]], pos[nodes])
    assert d.min() >= info["clearance_m"] * 0.999
    # the node budget is shared: what was taken off grew back
    assert info["regrown"] <= info["taken_off"]
    assert tree.n_nodes <= 200 + 1


def test_a_cut_placed_at_a_point(broad, limb):
    path, cut = limb
    at = (0.8, -0.3, 6.5)
    tree = _grow(broad, path, at=at, seed=37)
    nodes, info = _placed_nodes(tree)
    assert info["placed"] == "at" and info["at"] == list(at)
    # its base sits on the tree where the point is: no other node of the tree was nearer the point
    pos = tree.nodes3d[0].astype(np.float64)
    base = pos[info["base_node"]]
    own = np.setdiff1d(np.arange(tree.n_nodes), nodes)
    others = own[np.linalg.norm(pos[own] - at, axis=1) < np.linalg.norm(base - at) - 1e-9]
    assert len(others) <= info["regrown"]                     # only branches grown back after it may be nearer
    _check_unchanged(tree, cut, nodes, info)


def test_a_swaying_tree_keeps_its_cut(broad, limb):
    """In the wind the cut moves with the tree: its bones keep their lengths in every frame, and no
    twig grows on it (it stays as saved)."""
    path, cut = limb
    tree = _grow(broad, path, seed=53, wind=1.0, twigs=2)
    nodes, info = _placed_nodes(tree)
    L0 = cut.bone_lengths()
    for f in range(tree.n_frames):
        pos = tree.nodes3d[f].astype(np.float64)
        L = np.linalg.norm(pos[nodes] - pos[tree.parents[nodes]], axis=1)
        assert np.abs(L / L0 - 1).max() < 0.01
    twig0 = tree.meta["twigs"]["first_node"]
    assert tree.n_nodes > twig0 and not np.isin(tree.parents[twig0:], nodes).any()
    moved = np.linalg.norm(tree.nodes3d[:, nodes] - tree.nodes3d[0, nodes], axis=2).max()
    assert moved > 0.01                                        # it sways with the tree


def test_two_cuts_and_a_palm(broad, limb, tmp_path):
    path, cut = limb
    env = envelopes.envelope_from_any("circle", 10.0)
    p = growth.GrowParams(seed=61, n_frames=2, wind=0.0, twig_depth=0, leaf_density=0.0,
                          cuts=(cuts.CutSpec(path), cuts.CutSpec(path)))
    tree = growth.grow_tree(broad, env, p)
    a, b = tree.meta["cuts"]
    assert a["base_node"] != b["base_node"]
    for info in (a, b):
        nodes = np.arange(info["first_node"], info["first_node"] + info["bones"])
        _check_unchanged(tree, cut, nodes, info)
        assert np.allclose(tree.radius[nodes], cut.radius[1:], rtol=1e-6)
    palm = load_species_spec("palm")[0]
    assert palm.form == "palm"
    with pytest.raises(InputError, match="palms"):
        growth.grow_tree(palm, env, p)


# ----------------------------------------------------------------------------- the batch

def test_the_batch_places_cuts_and_refuses_bad_ones(limb, tmp_path):
    from test_generate_batch import run

    from tree_from_video.core import jobs
    from tree_from_video.core.tree3d import load_tree
    path, cut = limb
    out = tmp_path / "gen"
    code, err = run("--generate", 2, "--species", "sparse", "--nodes", 120, "--frames-out", 3, "--wind", 0,
                    "--no-leaves", "--cut", path, "--cut", f"{path}@0.5,0,6", "--seed", 71, "--out", out)
    assert code == 0, err
    for folder in ("tree_000", "tree_001"):
        tree = load_tree(out / folder / "tree3d.npz")
        fit, at = tree.meta["cuts"]
        assert fit["placed"] == "fit" and at["placed"] == "at" and at["at"] == [0.5, 0.0, 6.0]
        for info in (fit, at):
            nodes = np.arange(info["first_node"], info["first_node"] + info["bones"])
            _check_unchanged(tree, cut, nodes, info)
    job = jobs.from_flat({"generate": 1, "species": "broad", "cut": [path], "out": str(tmp_path / "j")})
    assert jobs.from_flat(jobs.to_flat(job)) == job and job.request.cuts == (path,)
    for bad, says in ((f"{path}@1,2", "X,Y,Z"), (str(tmp_path / "none.npz"), "does not exist")):
        code, err = run("--generate", 1, "--species", "broad", "--cut", bad, "--out", tmp_path / "bad")
        assert code == 2 and says in err and len(err.strip().splitlines()) == 1, err
        assert not (tmp_path / "bad").exists()


def test_a_cut_sticking_out_of_the_envelope_is_reported(broad, limb):
    """Placed by hand at the crown's top, most of the limb is outside the envelope: kept as placed
    (the user's choice), with a warning that gives the share."""
    path, cut = limb
    with pytest.warns(RuntimeWarning, match=r"only \d+% of its nodes are inside the envelope"):
        tree = _grow(broad, path, at=(0.0, 0.0, 9.9), seed=83)
    nodes, info = _placed_nodes(tree)
    assert info["inside_share"] < growth.CUT_INSIDE_WARN
    _check_unchanged(tree, cut, nodes, info)


def test_the_api_saves_and_places_cuts(tmp_path):
    from tree_from_video import api
    src = broad_tree(frames=2)
    path = api.save_cut(src, ["B040"], tmp_path / "limb.npz")
    cut = load_cut(path)
    assert cut.mesh is not None and list(cut.source_nodes) == list(cut_from_tree(src, ["B040"]).source_nodes)
    with pytest.raises(InputError, match="exists"):
        api.save_cut(src, ["B040"], path)
    (tree,) = api.generate("broad", 1, seed=97, n_frames=2, wind=0.0, twig_depth=0, leaf_density=0.0,
                           cuts=[f"{path}@0.4,0,5.5"])
    nodes, info = _placed_nodes(tree)
    assert info["placed"] == "at"
    _check_unchanged(tree, cut, nodes, info)



def test_a_kept_growth_grows_the_same_tree(broad, limb):
    """What a generated tree keeps (core/generate/regrow.py, through JSON) grows it again exactly,
    its cuts too: Place Cut's regrowth changes only what the new cut changes."""
    from tree_from_video.core.generate import regrow
    path, _ = limb
    env = envelopes.envelope_from_any("heart", 7.0)
    p = growth.GrowParams(seed=67, height_m=7.0, n_frames=3, node_budget=120, envelope_variation=0.3,
                          cuts=(cuts.CutSpec(path),))
    doc = json.loads(json.dumps(regrow.inputs_doc(broad, env, p, None)))
    model, env2, p2, audio = regrow.inputs_from_doc(doc)
    p2.cuts = p.cuts
    a, b = growth.grow_tree(broad, env, p), growth.grow_tree(model, env2, p2)
    assert p2 == p and audio is None
    assert np.array_equal(a.parents, b.parents) and np.array_equal(a.nodes3d, b.nodes3d)
    assert np.array_equal(a.radius, b.radius) and a.meta["cuts"] == b.meta["cuts"]
