"""The tree's materials: the procedural, UV-mapped bark of the branch mesh (Principled BSDF with
Voronoi cells and, for smooth/rough bark, furrows along the branch) and the leaf cards' material
(a packed leaf image, the user's or a procedural one, times the video's colour per vertex,
alpha cut-out, two-sided). The caller removes a material (and its images,
:func:`material_images`) when a build fails."""
from __future__ import annotations

import bpy
import numpy as np

from ...core.asset.look import bark_solid as bark_colour
from ...core.detail.albedo import srgb_to_linear
from ...core.detail.bark_texture import BARK_LOOK, BARK_RAMP, bark_ramp  # noqa: F401  (BARK_RAMP: re-exported)
from ...core.detail.leaf_texture import TEXTURE_SIZE, shape_pixels
from ...core.errors import InputError

#: custom properties of a bark material: its kind, and the video's bark colour (sRGB) if any
BARK_KEY = "tree_video_bark"
BARK_COLOUR_KEY = "tree_video_bark_colour"


#: custom property of a bark made from photos of bark (its images are real: nothing to bake at export)
BARK_PHOTO_KEY = "tree_video_bark_photo"


#: a material whose Principled Alpha is alpha-tested at 0.5 (the glTF export writes it as MASK)
ALPHA_CLIP_KEY = "tree_video_alpha_clip"


def principled_nodes(mat):
    """``mat``'s node tree emptied (nodes switched on first on Blender 4.x; 5.x always has them),
    with a Material Output and a Principled BSDF: ``(node_tree, output, bsdf)``."""
    if mat.node_tree is None:
        mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    return nt, nt.nodes.new("ShaderNodeOutputMaterial"), nt.nodes.new("ShaderNodeBsdfPrincipled")


def bark_material(name: str, kind: str = "none", colour=None) -> bpy.types.Material:
    """A Principled BSDF bark, procedural and UV-mapped (the bark follows the bending branches):
    noise colour around ``colour`` (sRGB, the tree's ``meta["bark_colour"]``; None: a brown-grey
    default), :func:`bark_ramp`; bump from Voronoi cells plus, for ``kind`` "smooth"/"rough", furrows
    along the branch (a distorted Wave texture in bands across u, i.e. running along v), with the
    strengths of :data:`BARK_LOOK`. The caller removes it on failure."""
    strength, furrow = BARK_LOOK.get(kind, BARK_LOOK["none"])
    ramp_ends = bark_ramp(colour)
    mat = bpy.data.materials.new(name)
    try:
        mat.diffuse_color = bark_colour(colour)              # solid-view colour: the bark's own
        mat.roughness = 0.9
        mat[BARK_KEY] = kind                                 # what an export bakes to images
        if colour is not None:
            mat[BARK_COLOUR_KEY] = [float(c) for c in np.asarray(colour, np.float64)[:3]]
        nt, out, bsdf = principled_nodes(mat)
        coord = nt.nodes.new("ShaderNodeTexCoord")
        mapping = nt.nodes.new("ShaderNodeMapping")
        noise = nt.nodes.new("ShaderNodeTexNoise")
        voronoi = nt.nodes.new("ShaderNodeTexVoronoi")
        ramp = nt.nodes.new("ShaderNodeValToRGB")
        bump = nt.nodes.new("ShaderNodeBump")
        for i, node in enumerate((coord, mapping, noise, voronoi, ramp, bump, bsdf, out)):
            node.location = (220 * i - 900, 150 * ((i % 2) * 2 - 1))
        mapping.inputs["Scale"].default_value = (4.0, 6.0, 4.0)
        noise.inputs["Scale"].default_value = 3.0
        noise.inputs["Detail"].default_value = 8.0
        voronoi.inputs["Scale"].default_value = 5.0
        ramp.color_ramp.elements[0].color, ramp.color_ramp.elements[1].color = ramp_ends
        bump.inputs["Strength"].default_value = strength
        bsdf.inputs["Roughness"].default_value = 0.9
        link = nt.links.new
        link(coord.outputs["UV"], mapping.inputs["Vector"])
        link(mapping.outputs["Vector"], noise.inputs["Vector"])
        link(mapping.outputs["Vector"], voronoi.inputs["Vector"])
        link(noise.outputs["Fac"], ramp.inputs["Fac"])
        link(ramp.outputs["Color"], bsdf.inputs["Base Color"])
        height = voronoi.outputs["Distance"]
        if furrow > 0:
            wave = nt.nodes.new("ShaderNodeTexWave")
            wave.wave_type = "BANDS"
            wave.bands_direction = "X"                       # bands across u: furrows along the branch
            wave.inputs["Scale"].default_value = 2.0
            wave.inputs["Distortion"].default_value = 6.0
            wave.inputs["Detail"].default_value = 4.0
            mix = nt.nodes.new("ShaderNodeMath")
            mix.operation = "MULTIPLY_ADD"                   # wave · furrow + Voronoi distance
            mix.inputs[1].default_value = furrow
            wave.location, mix.location = (-460, -350), (-240, -350)
            link(mapping.outputs["Vector"], wave.inputs["Vector"])
            link(wave.outputs["Fac"], mix.inputs[0])
            link(voronoi.outputs["Distance"], mix.inputs[2])
            height = mix.outputs["Value"]
        link(height, bump.inputs["Height"])
        link(bump.outputs["Normal"], bsdf.inputs["Normal"])
        link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    except BaseException:
        bpy.data.materials.remove(mat)
        raise
    return mat


def photo_bark_material(name: str, albedo: np.ndarray, normal: np.ndarray, roughness: np.ndarray,
                        repeats: int) -> bpy.types.Material:
    """A Principled BSDF bark from photos of bark (:mod:`core.detail.bark_photo`): the UV square's
    ``albedo (P, P, 3)`` uint8 sRGB into Base Color, ``normal`` (tangent space) through a Normal Map
    node, ``roughness (P, P)`` in [0, 1] into Roughness; three images packed into the .blend, which
    every exporter carries (glTF ``baseColorTexture``/``normalTexture``, FBX embedded, USD beside).
    The name keeps ``Bark``; ``repeats`` tiles go once round the trunk. The caller removes it (and
    its images, :func:`material_images`) on failure."""
    def rgba(a: np.ndarray) -> np.ndarray:          # (P, P[, 3]) uint8/float, row 0 at the top → Blender's
        f = a.astype(np.float32) / (255.0 if a.dtype == np.uint8 else 1.0)
        f = np.repeat(f[..., None], 3, -1) if f.ndim == 2 else f
        out = np.ones(f.shape[:2] + (4,), np.float32)
        out[..., :3] = f[::-1]
        return out
    mat = bpy.data.materials.new(name)
    images: list = []
    try:
        mat.diffuse_color = (*(srgb_to_linear(albedo.reshape(-1, 3).mean(0) / 255.0)).tolist(), 1.0)
        mat[BARK_KEY] = "photo"
        mat[BARK_PHOTO_KEY] = int(repeats)
        nt, out, bsdf = principled_nodes(mat)
        for suffix, pixels, space in (("albedo", albedo, "sRGB"), ("normal", normal, "Non-Color"),
                                      ("roughness", roughness, "Non-Color")):
            images.append(packed_image(f"{name} {suffix}", rgba(pixels), space, False))
        a_node, n_node, r_node, map_node = (nt.nodes.new(t) for t in ("ShaderNodeTexImage", "ShaderNodeTexImage",
                                                                      "ShaderNodeTexImage", "ShaderNodeNormalMap"))
        for node, img in zip((a_node, n_node, r_node), images):
            node.image = img
        for i, node in enumerate((a_node, n_node, r_node)):
            node.location = (-700, 300 - 300 * i)
        map_node.location, bsdf.location, out.location = (-350, -300), (0, 0), (300, 0)
        link = nt.links.new
        link(a_node.outputs["Color"], bsdf.inputs["Base Color"])
        link(r_node.outputs["Color"], bsdf.inputs["Roughness"])
        link(n_node.outputs["Color"], map_node.inputs["Color"])
        link(map_node.outputs["Normal"], bsdf.inputs["Normal"])
        link(bsdf.outputs["BSDF"], out.inputs["Surface"])
    except BaseException:
        bpy.data.materials.remove(mat)
        for img in images:
            bpy.data.images.remove(img)
        raise
    return mat


def leaf_image(name: str, path: str | None, tint=(1.0, 1.0, 1.0), shape: str = "cluster"):
    """The leaf texture: the user's image at ``path`` (packed into the .blend), or the procedural
    one of the leaf ``shape`` (:func:`core.detail.leaf_texture.shape_pixels`: a broad leaf, a
    conifer's needle spray). Raises InputError for an image Blender cannot read."""
    if path:
        try:
            img = bpy.data.images.load(path, check_existing=False)
        except RuntimeError as exc:
            raise InputError(f"cannot read the leaf image '{path}' ({exc}); pick a PNG/JPEG/TIFF with the "
                             "leaf's shape in its alpha channel, or clear the field") from None
        if img.size[0] == 0 or img.size[1] == 0:
            bpy.data.images.remove(img)
            raise InputError(f"'{path}' is not an image Blender can read; pick a PNG/JPEG/TIFF leaf, or clear "
                             "the field for the procedural leaf")
        try:
            img.pack()
        except RuntimeError:
            bpy.data.images.remove(img)
            raise
        return img
    return packed_image(f"{name} Texture", shape_pixels(shape, TEXTURE_SIZE, tint))


def packed_image(name: str, rgba: np.ndarray, colorspace: str | None = None, alpha: bool = True):
    """A new image ``name`` of ``rgba (H, W, 4)`` float pixels (row 0 at the bottom), packed as PNG
    into the .blend (exporters embed it); ``colorspace`` e.g. "Non-Color" for a normal map."""
    h, w = rgba.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=alpha)
    if colorspace is not None:
        img.colorspace_settings.name = colorspace
    img.pixels.foreach_set(np.asarray(rgba, np.float32).ravel())
    img.file_format = "PNG"
    img.pack()
    return img


def leaf_material(name: str, image_path: str | None = None, tint=(0.3, 0.5, 0.2),
                  colour=None, shape: str = "cluster") -> bpy.types.Material:
    """Leaf material: the leaf image (``image_path`` or procedural, packed; alpha cut-out at 0.5,
    which glTF writes as ``alphaMode`` MASK: :data:`ALPHA_CLIP_KEY`)
    multiplied by the mesh's ``Col`` colour attribute (the video's colour), Principled BSDF,
    two-sided; ``tint`` (sRGB, :func:`core.asset.look.leaf_tint`) colours the procedural leaf, ``colour`` (sRGB,
    :func:`leaf_colour`; None: ``tint``) the solid view (Viewport Display colour). The caller
    removes it (and its image, via :func:`material_images`) on failure."""
    mat = bpy.data.materials.new(name)
    img = None
    try:
        solid = np.asarray(tint if colour is None else colour, np.float64)
        mat.diffuse_color = (*srgb_to_linear(np.clip(solid, 0.0, 1.0)), 1.0)
        if hasattr(mat, "surface_render_method"):          # EEVEE Next (4.2+)
            mat.surface_render_method = "DITHERED"
        if hasattr(mat, "blend_method"):
            try:
                mat.blend_method = "CLIP"
            except TypeError:
                pass
        mat.use_backface_culling = False
        img = leaf_image(name, image_path, tint, shape)
        nt, out, bsdf = principled_nodes(mat)
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = img
        attr = nt.nodes.new("ShaderNodeVertexColor")
        attr.layer_name = "Col"
        mix = nt.nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        mix.blend_type = "MULTIPLY"
        mix.inputs["Factor"].default_value = 1.0
        for i, node in enumerate((tex, attr, mix, bsdf, out)):
            node.location = (260 * i - 700, 120 * ((i % 2) * 2 - 1))
        sock = {s.identifier: s for s in mix.inputs}
        out_sock = {s.identifier: s for s in mix.outputs}
        link = nt.links.new
        link(tex.outputs["Color"], sock["A_Color"])
        link(attr.outputs["Color"], sock["B_Color"])
        link(out_sock["Result_Color"], bsdf.inputs["Base Color"])
        # alpha-tested, not blended: the glTF export puts a Round node on this link (alphaMode MASK,
        # cutoff 0.5; export.py); a direct link is what the FBX exporter reads as the alpha texture
        link(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
        mat[ALPHA_CLIP_KEY] = True
        bsdf.inputs["Roughness"].default_value = 0.6
        link(bsdf.outputs["BSDF"], out.inputs["Surface"])
        out.target = "ALL"                  # what the exporters read: a Principled BSDF on the output
        translucent_outputs(nt, bsdf, out_sock["Result_Color"], tex.outputs["Alpha"])
    except BaseException:
        bpy.data.materials.remove(mat)
        if img is not None:
            bpy.data.images.remove(img)
        raise
    return mat


#: share of the light a leaf passes through to its other side (Translucent BSDF in the render)
LEAF_TRANSLUCENCY = 0.3


def translucent_outputs(nt, bsdf, colour_socket, alpha_socket) -> None:
    """Material outputs for EEVEE and Cycles in ``nt`` (a leaf's node tree): the Principled ``bsdf``
    mixed with a Translucent BSDF of the leaf's colour (``LEAF_TRANSLUCENCY`` of it), cut out by
    the leaf's alpha (a Transparent BSDF outside the blade), so a backlit crown glows as a real one
    does. The output targeting ALL keeps the plain Principled BSDF: FBX, glTF and USD read that."""
    tr = nt.nodes.new("ShaderNodeBsdfTranslucent")
    clear = nt.nodes.new("ShaderNodeBsdfTransparent")
    lit = nt.nodes.new("ShaderNodeMixShader")
    cut = nt.nodes.new("ShaderNodeMixShader")
    lit.inputs[0].default_value = LEAF_TRANSLUCENCY
    link = nt.links.new
    link(colour_socket, tr.inputs["Color"])
    link(bsdf.outputs["BSDF"], lit.inputs[1])
    link(tr.outputs["BSDF"], lit.inputs[2])
    link(alpha_socket, cut.inputs[0])                   # alpha 0: transparent, 1: the lit leaf
    link(clear.outputs["BSDF"], cut.inputs[1])
    link(lit.outputs["Shader"], cut.inputs[2])
    for i, node in enumerate((tr, clear, lit, cut)):
        node.location = (260 * i - 440, -420)
    for i, target in enumerate(("EEVEE", "CYCLES")):
        o = nt.nodes.new("ShaderNodeOutputMaterial")
        o.target = target
        o.location = (700, -420 - 200 * i)
        link(cut.outputs["Shader"], o.inputs["Surface"])


def material_images(mat) -> list:
    """Images used by ``mat``'s node tree (to remove them with it)."""
    if mat is None or mat.node_tree is None:
        return []
    return [n.image for n in mat.node_tree.nodes if n.type == "TEX_IMAGE" and n.image is not None]

