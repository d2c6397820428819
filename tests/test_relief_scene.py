"""Bark relief in Blender and its exports (issue 36 part 3): the tree built with *Bark Relief* has
the core's displaced tubes as its mesh, and the glTF and FBX files carry the same vertices (read
back from the files as their formats lay them out, not through Blender's importers), not the
smooth ones."""
import bpy
import numpy as np
import pytest
from fbx_reader import child, read_fbx, top
from scipy.spatial import cKDTree
from test_exports import accessor, read_glb

from tree_from_video.core.asset.meshes import branch_arrays
from tree_from_video.core.detail import branch_mesh as bm
from tree_from_video.core.detail.relief import RELIEF_RINGS, RELIEF_SIDES
from tree_from_video.operators.scene import build, export

from trees import (
    broad_tree,
    empty_scene,  # noqa: F401  (autouse fixture)
    rig_rest,
)

pytestmark = [pytest.mark.blender, pytest.mark.bpy53]

DEPTH_CM = 3.0


def _matches(found, want, tol):
    """Largest distance from a file's vertex to the nearest wanted vertex, and back."""
    return (float(cKDTree(want).query(found)[0].max()), float(cKDTree(found).query(want)[0].max()))


def test_relief_in_blender_gltf_and_fbx(tmp_path):
    tree = broad_tree(6)
    res = build.build_tree(bpy.context, tree, "Tree", curliness=0.3, bark="rough", relief_cm=DEPTH_CM, leaves=False)
    rest = rig_rest(res["armature"], tree)
    want = branch_arrays(tree, rest, bm.MeshParams(curliness=0.3, bark="rough", relief_cm=DEPTH_CM)).co
    smooth = branch_arrays(tree, rest, bm.MeshParams(curliness=0.3, bark="rough", sides=RELIEF_SIDES,
                                                     rings=RELIEF_RINGS)).co
    me = res["mesh"].data
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    np.testing.assert_allclose(co.reshape(-1, 3), want, atol=1e-5)          # Blender's mesh is the core's
    apart = float(np.linalg.norm(want - smooth, axis=1).max())
    assert apart > 0.3 * DEPTH_CM / 100                                      # the relief is there to find

    objects = [res["armature"], res["mesh"]]
    glb = export.export_gltf(tmp_path / "tree.glb", objects)
    doc, binary = read_glb(glb)
    mesh = next(m for m in doc["meshes"] if "Branches" in m["name"])
    pos = np.concatenate([accessor(doc, binary, p["attributes"]["POSITION"]) for p in mesh["primitives"]])
    zup = np.stack([pos[:, 0], -pos[:, 2], pos[:, 1]], axis=1)              # glTF +Y up → Blender +Z up
    g = _matches(zup, want, 1e-4)
    s = _matches(zup, smooth, 1e-4)

    fbx = export.export_fbx(tmp_path / "tree.fbx", objects)
    geom = [n for n in child(top(read_fbx(fbx), "Objects"), "Geometry") if b"Branches" in n["props"][1]]
    verts = np.asarray(child(geom[0], "Vertices")[0]["props"][0], np.float64).reshape(-1, 3)
    f = _matches(verts, want, 1e-4)
    print(f"\nrelief {DEPTH_CM} cm: largest vertex move {100 * apart:.2f} cm; glTF off the relief mesh "
          f"{1000 * max(g):.3f} mm (off the smooth one {1000 * max(s):.2f} mm); FBX off {1000 * max(f):.3f} mm")
    assert max(g) < 1e-4 and max(f) < 1e-4
    assert max(s) > 0.3 * DEPTH_CM / 100
