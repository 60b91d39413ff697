"""Procedural Cycles materials and greenhouse lighting, built as node trees in `bpy`.

The recipes (node trees) live here; their numbers (colours, roughness, coat, blotches,
translucency) come from the material table `scene/materials.py`, the one place to
change a material for every view. Everything is procedural (no image textures to ship
or load) and every random choice comes from the generator the caller passes, so one
scene seed gives one look. Colours in `scene.json` and the table are display (sRGB)
values, as a person would pick them and as the MuJoCo raster view shows them; Cycles
shades in linear Rec.709, so constants and per-object colours go through
`srgb_to_linear` first.

Per-instance colours are not baked into one material per object: peppers read
their colour from the object's `color` (Object Info node) and the merged leaf
mesh of a plant from a per-vertex attribute `leaf_rgb`, so a plant of 50 leaves
is one object and one material, which keeps Cycles' scene sync short. The 'pepper'
style's leaves are instances of a few template meshes, so each copy is an object
and reads its colour and its dust from the object's `color` (RGB and alpha); its
fruit read their ripe share from the alpha. Inside a plant prototype, which each
copy of the plant instances whole, the leaves are one merged mesh instead, and the
leaf material's per-vertex variant (`per_vertex_name`) reads each leaf's colour, dust and
place from attributes of its vertices.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import bpy
import numpy as np
from mathutils import Matrix

from renderloop.render.sky import SKY_HORIZON, SKY_RAMP, SKY_STRENGTH, SKY_ZENITH
from renderloop.render.srgb import to_linear
from renderloop.scene.materials import DAYLIGHT, MATERIALS, Material
from renderloop.scene.meshes import frame_from_axis
from renderloop.scene.model import Environment
from renderloop.scene.objects import film_tint

LEAF_COLOR_ATTRIBUTE = "leaf_rgb"  # a leaf's linear colour per vertex; its alpha, in merged copies, the copy's alpha
COPY_OBJECT_ATTRIBUTE = "copy_object"  # in merged copies: a vertex where it lies in its copy's own template
COPY_PLACE_ATTRIBUTE = "copy_place"  # in merged copies: where its copy stands in the merged mesh's frame


def per_vertex_name(name: str) -> str:
    """The name of the variant of material `name` that reads from its vertices what it reads from its object."""
    return f"{name}@per_vertex"


def srgb_to_linear(rgb: Sequence[float]) -> tuple[float, float, float]:
    """One sRGB colour as the linear triple a node socket takes."""
    lin = to_linear(np.asarray(rgb, dtype=float)[:3])
    return float(lin[0]), float(lin[1]), float(lin[2])


class _Tree:
    """Terse node-tree building: one call per node, sockets by name or index."""

    def __init__(self, tree: bpy.types.NodeTree) -> None:
        self.tree = tree
        tree.nodes.clear()

    def node(self, kind: str, inputs: dict | None = None, **props):
        node = self.tree.nodes.new(kind)
        for key, value in props.items():
            setattr(node, key, value)
        for key, value in (inputs or {}).items():
            socket = node.inputs[key]
            if isinstance(value, bpy.types.NodeSocket):
                self.tree.links.new(value, socket)
            else:
                socket.default_value = value
        return node

    def math(self, operation: str, a, b=0.0, clamp: bool = False) -> bpy.types.NodeSocket:
        return self.node("ShaderNodeMath", {0: a, 1: b}, operation=operation, use_clamp=clamp).outputs[0]

    def map_range(self, value, from_min: float, from_max: float, to_min: float = 0.0, to_max: float = 1.0,
                  smooth: bool = False) -> bpy.types.NodeSocket:
        node = self.node("ShaderNodeMapRange", {0: value, 1: from_min, 2: from_max, 3: to_min, 4: to_max},
                         interpolation_type="SMOOTHSTEP" if smooth else "LINEAR", clamp=True)
        return node.outputs[0]

    def mix_rgb(self, factor, a, b, blend: str = "MIX") -> bpy.types.NodeSocket:
        """ShaderNodeMix in RGBA mode; its colour sockets are inputs 6, 7 and output 2."""
        node = self.node("ShaderNodeMix", data_type="RGBA", blend_type=blend)
        for index, value in ((0, factor), (6, a), (7, b)):
            if isinstance(value, bpy.types.NodeSocket):
                self.tree.links.new(value, node.inputs[index])
            else:
                node.inputs[index].default_value = value if index == 0 else (*value[:3], 1.0)
        return node.outputs[2]

    def noise(self, scale: float, detail: float = 2.0, coords: str = "Object") -> bpy.types.NodeSocket:
        texcoord = self.node("ShaderNodeTexCoord")
        return self.node("ShaderNodeTexNoise", {"Vector": texcoord.outputs[coords], "Scale": scale, "Detail": detail}).outputs["Fac"]

    def output(self, shader: bpy.types.NodeSocket, kind: str = "ShaderNodeOutputMaterial") -> None:
        out = self.node(kind, target="CYCLES") if kind == "ShaderNodeOutputMaterial" else self.node(kind)
        self.tree.links.new(shader, out.inputs[0])


def _principled(t: _Tree, color, roughness, look: Material, **inputs) -> bpy.types.NodeSocket:
    """A Principled BSDF with the table's numbers; inputs at Blender's defaults are left untouched."""
    values = {"Base Color": color if isinstance(color, bpy.types.NodeSocket) else (*color, 1.0), "Roughness": roughness}
    if look.metallic:
        values["Metallic"] = look.metallic
    if look.specular is not None:
        values["Specular IOR Level"] = look.specular
    if look.coat:
        values.update({"Coat Weight": look.coat, "Coat Roughness": look.coat_roughness})
    if look.subsurface:
        values["Subsurface Weight"] = look.subsurface
        if look.subsurface_scale is not None:
            values["Subsurface Scale"] = look.subsurface_scale
    if look.sheen:
        values.update({"Sheen Weight": look.sheen, "Sheen Roughness": look.sheen_roughness})
    values.update(inputs)
    # Burley's diffusion model: over a fruit wall's few millimetres it looks as the random walk does, and costs less
    props = {"subsurface_method": "BURLEY"} if look.subsurface else {}
    return t.node("ShaderNodeBsdfPrincipled", values, **props).outputs[0]


def _new_material(name: str) -> tuple[bpy.types.Material, _Tree]:
    material = bpy.data.materials.new(name)
    return material, _Tree(material.node_tree)


def _varied(t: _Tree, color, scale: float, amount: float) -> bpy.types.NodeSocket:
    """Colour times a low-frequency noise in [1 - amount, 1 + amount]: blotches instead of flat paint."""
    gain = t.map_range(t.noise(scale), 0.3, 0.7, 1.0 - amount, 1.0 + amount)
    return t.mix_rgb(1.0, color, t.node("ShaderNodeCombineXYZ", {0: gain, 1: gain, 2: gain}).outputs[0], "MULTIPLY")


def _translucent(t: _Tree, look: Material, surface: bpy.types.NodeSocket, color) -> bpy.types.NodeSocket:
    """The surface with a share of Translucent BSDF in `color`: light through a thin blade or petal."""
    glow = t.node("ShaderNodeBsdfTranslucent", {"Color": color}).outputs[0]
    return t.node("ShaderNodeMixShader", {0: look.translucency, 1: surface, 2: glow}).outputs[0]


def leaf_material(name: str = "leaf") -> bpy.types.Material:
    """Leaf blade: per-leaf colour attribute, midrib and lateral veins from the leaf uv
    (u along the midrib 0..1, v across, 0.5 on the midrib), blotchy variation, a vein
    bump, and a Translucent BSDF share so back-lit leaves glow as real canopies do."""
    look = MATERIALS[name]
    material, t = _new_material(name)
    uv = t.node("ShaderNodeSeparateXYZ", {0: t.node("ShaderNodeTexCoord").outputs["UV"]})
    u, across = uv.outputs[0], t.math("ABSOLUTE", t.math("SUBTRACT", uv.outputs[1], 0.5))
    midrib = t.map_range(across, 0.0, 0.035, 1.0, 0.0, smooth=True)
    phase = t.math("SUBTRACT", t.math("MULTIPLY", u, 9.0), t.math("MULTIPLY", across, 8.0))
    lateral = t.map_range(t.math("PINGPONG", phase, 0.5), 0.0, 0.06, 1.0, 0.0, smooth=True)
    lateral = t.math("MULTIPLY", lateral, t.map_range(across, 0.28, 0.42, 0.7, 0.0))
    lateral = t.math("MULTIPLY", lateral, t.map_range(u, 0.85, 0.97, 1.0, 0.0))
    veins = t.math("MAXIMUM", midrib, lateral)
    base = t.node("ShaderNodeAttribute", attribute_type="GEOMETRY", attribute_name=LEAF_COLOR_ATTRIBUTE).outputs["Color"]
    base = _varied(t, base, look.variation_scale, look.variation)
    vein_color = t.mix_rgb(1.0, base, look.vein_gain, "MULTIPLY")
    color = t.mix_rgb(t.math("MULTIPLY", veins, 0.65), base, vein_color)
    bump = t.node("ShaderNodeBump", {"Strength": look.bump, "Height": veins})
    surface = _principled(t, color, look.roughness, look, Normal=bump.outputs[0])
    t.output(_translucent(t, look, surface, t.mix_rgb(1.0, color, look.glow_gain, "MULTIPLY")))
    return material


def pepper_material(name: str) -> bpy.types.Material:
    """Glossy, waxy fruit skin; the base colour is the object's colour (pepper.rgb), with slight
    blotchy variation, so one material serves every pepper of a colour class."""
    look = MATERIALS[name]
    material, t = _new_material(name)
    color = _varied(t, t.node("ShaderNodeObjectInfo").outputs["Color"], look.variation_scale, look.variation)
    low, high = look.roughness_range
    rough = t.map_range(t.noise(look.roughness_scale), 0.3, 0.7, look.roughness * low, look.roughness * high)
    t.output(_principled(t, color, rough, look))
    return material


def _vector(t: _Tree, operation: str, a, b) -> bpy.types.NodeSocket:
    node = t.node("ShaderNodeVectorMath", operation=operation)
    for index, value in ((0, a), ("Scale" if operation == "SCALE" else 1, b)):
        if isinstance(value, bpy.types.NodeSocket):
            t.tree.links.new(value, node.inputs[index])
        else:
            node.inputs[index].default_value = value
    return node.outputs[0]


def _per_copy(t: _Tree, own: bpy.types.NodeSocket, place: bpy.types.NodeSocket) -> bpy.types.NodeSocket:
    """Texture coordinates that differ from copy to copy of one mesh: its own object space `own`, shifted by
    where the copy stands (`place`), so two leaves of one template do not carry the same blotches."""
    return _vector(t, "ADD", own, _vector(t, "SCALE", place, 37.0))


def _copy_values(t: _Tree, per_vertex: bool) -> tuple[bpy.types.NodeSocket, ...]:
    """A copy's colour, alpha and texture coordinates (`_per_copy`): from its object, or, for copies merged into
    one mesh, from its vertices' attributes, its place then theirs plus where the merged mesh stands (in an
    instanced prototype, the plant's copy)."""
    info = t.node("ShaderNodeObjectInfo")
    if not per_vertex:
        return info.outputs["Color"], info.outputs["Alpha"], _per_copy(
            t, t.node("ShaderNodeTexCoord").outputs["Object"], info.outputs["Location"])
    color = t.node("ShaderNodeAttribute", attribute_type="GEOMETRY", attribute_name=LEAF_COLOR_ATTRIBUTE)
    own = t.node("ShaderNodeAttribute", attribute_type="GEOMETRY", attribute_name=COPY_OBJECT_ATTRIBUTE).outputs["Vector"]
    place = t.node("ShaderNodeAttribute", attribute_type="GEOMETRY", attribute_name=COPY_PLACE_ATTRIBUTE).outputs["Vector"]
    return color.outputs["Color"], color.outputs["Alpha"], _per_copy(t, own, _vector(t, "ADD", place, info.outputs["Location"]))


def _noise_at(t: _Tree, coords, scale: float, detail: float = 2.0) -> bpy.types.NodeSocket:
    return t.node("ShaderNodeTexNoise", {"Vector": coords, "Scale": scale, "Detail": detail}).outputs["Fac"]


def pepper_leaf_material(name: str = "pepper_leaf", per_vertex: bool = False) -> bpy.types.Material:
    """A sweet-pepper leaf, one material for every copy of every template. The copy's colour and dust come
    from its object (Object Info Color and Alpha), or with `per_vertex` from its vertices (`_copy_values`).
    From the template's uv (u along the midrib, v across, 0.5
    on it): the midrib, seven pairs of lateral veins curving toward the tip and a fine network between them,
    paler than the blade and sunk into it (bump). Blotches and a yellower cast that differ from copy to copy,
    a paler underside, a grey film where dusty, a waxy coat and grey sheen, and a Translucent share so
    back-lit leaves glow."""
    look = MATERIALS[name]
    material, t = _new_material(per_vertex_name(name) if per_vertex else name)
    own_color, own_alpha, coords = _copy_values(t, per_vertex)
    texcoord = t.node("ShaderNodeTexCoord")
    uv = t.node("ShaderNodeSeparateXYZ", {0: texcoord.outputs["UV"]})
    u, across = uv.outputs[0], t.math("ABSOLUTE", t.math("SUBTRACT", uv.outputs[1], 0.5))
    midrib = t.map_range(across, 0.0, 0.022, 1.0, 0.0, smooth=True)
    phase = t.math("MULTIPLY", t.math("SUBTRACT", u, t.math("MULTIPLY", across, 0.9)), 7.0)
    lateral = t.map_range(t.math("PINGPONG", phase, 0.5), 0.0, 0.045, 1.0, 0.0, smooth=True)
    lateral = t.math("MULTIPLY", lateral, t.map_range(across, 0.3, 0.46, 1.0, 0.0))
    lateral = t.math("MULTIPLY", lateral, t.map_range(u, 0.05, 0.12, 0.0, 1.0))
    lateral = t.math("MULTIPLY", lateral, t.map_range(u, 0.85, 0.97, 1.0, 0.0))
    blade_uv = _vector(t, "MULTIPLY", texcoord.outputs["UV"], (1.0, 0.48, 0.0))  # isotropic on the blade
    cells = t.node("ShaderNodeTexVoronoi", {"Vector": blade_uv, "Scale": 28.0}, feature="DISTANCE_TO_EDGE")
    network = t.map_range(cells.outputs["Distance"], 0.0, 0.05, look.reticulate, 0.0)
    veins = t.math("MAXIMUM", t.math("MAXIMUM", midrib, lateral), network)

    blotch = _noise_at(t, coords, look.variation_scale, 3.0)
    gain = t.map_range(blotch, 0.3, 0.7, 1.0 - look.variation, 1.0 + look.variation)
    base = t.mix_rgb(1.0, own_color, t.node("ShaderNodeCombineXYZ", {0: gain, 1: gain, 2: gain}).outputs[0], "MULTIPLY")
    yellower = t.mix_rgb(1.0, base, (1.25, 1.2, 0.6), "MULTIPLY")
    base = t.mix_rgb(t.map_range(blotch, 0.5, 0.8, 0.0, 0.3), base, yellower)
    color = t.mix_rgb(t.math("MULTIPLY", veins, 0.8), base, t.mix_rgb(1.0, base, look.vein_gain, "MULTIPLY"))
    underside = t.node("ShaderNodeNewGeometry").outputs["Backfacing"]
    color = t.mix_rgb(underside, color, t.mix_rgb(1.0, color, look.underside_gain, "MULTIPLY"))
    patchy = t.map_range(_noise_at(t, coords, 2.5 * look.variation_scale), 0.35, 0.65, 0.3 * look.dust, look.dust)
    dust = t.math("MULTIPLY", own_alpha, patchy)
    color = t.mix_rgb(dust, color, srgb_to_linear(look.accent_rgb))
    roughness = t.math("ADD", look.roughness, t.math("MULTIPLY", dust, 0.4))
    height = t.math("SUBTRACT", t.math("MULTIPLY", _noise_at(t, coords, 6.0 * look.variation_scale), 0.3), veins)
    bump = t.node("ShaderNodeBump", {"Strength": look.bump, "Height": height})
    surface = _principled(t, color, roughness, look, Normal=bump.outputs[0])
    t.output(_translucent(t, look, surface, t.mix_rgb(1.0, color, look.glow_gain, "MULTIPLY")))
    return material


def fruit_material(name: str) -> bpy.types.Material:
    """The 'pepper' style's fruit skin: the object's colour where the skin has turned and the unripe green
    where not, in noise patches whose extent is the fruit's ripe share (Object Info Alpha; 1: all its colour),
    turning from the blossom end (uv v = 1) first, brown where the two meet; slight blotches, a few brown
    blemishes; glossy wax coat over a little subsurface light, its roughness varying over the skin."""
    look = MATERIALS[name]
    material, t = _new_material(name)
    info = t.node("ShaderNodeObjectInfo")
    texcoord = t.node("ShaderNodeTexCoord")
    share = info.outputs["Alpha"]
    along = t.node("ShaderNodeSeparateXYZ", {0: texcoord.outputs["UV"]}).outputs[1]
    patches = _noise_at(t, texcoord.outputs["Object"], 2.0 * look.variation_scale, 4.0)
    turning = t.math("ADD", t.math("MULTIPLY", patches, 0.7), t.math("MULTIPLY", along, 0.3))
    threshold = t.math("SUBTRACT", 0.85, t.math("MULTIPLY", share, 0.7))
    turned = t.map_range(turning, t.math("SUBTRACT", threshold, 0.02), t.math("ADD", threshold, 0.02), smooth=True)
    edge = t.map_range(t.math("ABSOLUTE", t.math("SUBTRACT", turning, threshold)), 0.0, 0.07, 1.0, 0.0)
    brown = t.math("MULTIPLY", edge, t.math("MULTIPLY", t.math("SUBTRACT", 1.0, share), 4.0, clamp=True))
    color = t.mix_rgb(turned, srgb_to_linear(look.unripe_rgb), info.outputs["Color"])
    color = t.mix_rgb(t.math("MULTIPLY", brown, 0.75), color, srgb_to_linear(look.accent_rgb))
    color = _varied(t, color, look.variation_scale, look.variation)
    spots = t.node("ShaderNodeTexVoronoi", {"Vector": texcoord.outputs["Object"], "Scale": 220.0})
    gate = t.map_range(_noise_at(t, texcoord.outputs["Object"], 9.0), 0.72 - look.blemish, 0.74 - look.blemish, 0.0, 1.0)
    spotted = t.math("MULTIPLY", t.map_range(spots.outputs["Distance"], 0.1, 0.16, 1.0, 0.0), gate)
    color = t.mix_rgb(t.math("MULTIPLY", spotted, 0.8), color, srgb_to_linear(look.accent_rgb))
    low, high = look.roughness_range
    rough = t.map_range(t.noise(look.roughness_scale), 0.3, 0.7, look.roughness * low, look.roughness * high)
    rough = t.math("ADD", rough, t.math("MULTIPLY", spotted, 0.3))
    t.output(_principled(t, color, rough, look))
    return material


def flower_material(name: str = "flower") -> bpy.types.Material:
    """Pale petals with a coloured centre: the flower's planar uv puts its centre at (0.5, 0.5)."""
    look = MATERIALS[name]
    material, t = _new_material(name)
    uv = t.node("ShaderNodeTexCoord").outputs["UV"]
    radius = t.node("ShaderNodeVectorMath", {0: uv, 1: (0.5, 0.5, 0.0)}, operation="DISTANCE").outputs["Value"]
    centre = t.map_range(radius, 0.1, 0.14, 1.0, 0.0, smooth=True)
    color = t.mix_rgb(centre, srgb_to_linear(look.base_rgb), srgb_to_linear(look.accent_rgb))
    t.output(_translucent(t, look, _principled(t, color, look.roughness, look), color))
    return material


def plain_material(name: str) -> bpy.types.Material:
    """Principled surface of the table's colour, or of the object's colour where it has none."""
    look = MATERIALS[name]
    material, t = _new_material(name)
    color = t.node("ShaderNodeObjectInfo").outputs["Color"] if look.base_rgb is None else srgb_to_linear(look.base_rgb)
    if look.variation > 0:
        color = _varied(t, color, look.variation_scale, look.variation)
    t.output(_principled(t, color, look.roughness, look))
    return material


def _grey(t: _Tree, value: bpy.types.NodeSocket) -> bpy.types.NodeSocket:
    """A grey colour of the value in every channel."""
    return t.node("ShaderNodeCombineXYZ", {i: value for i in range(3)}).outputs[0]


def film_material(name: str = "film") -> bpy.types.Material:
    """Greenhouse film: a share of the light goes straight through (Transparent, so the sun and sky reach the crop
    and cast soft shadows, shadow rays included), a share is scattered (Translucent: the film glows), a little is
    reflected. How much of each goes from the table's new to its old numbers with the film's age (the object's
    alpha), its tint is the object's colour, with dirt in blotches. Only camera and glossy rays see the glow: the
    light it sheds on the crop comes from the soft light under the roof (`film_lighting`), which one sample
    finds, where a path through the film and on to the sun mostly would not."""
    look = MATERIALS[name]
    material, t = _new_material(name)
    info = t.node("ShaderNodeObjectInfo")
    age = info.outputs["Alpha"]
    through = t.map_range(age, 0.0, 1.0, *look.transmission)
    haze = t.map_range(age, 0.0, 1.0, *look.haze)
    clear = t.math("MULTIPLY", through, t.math("SUBTRACT", 1.0, haze))
    tint = _varied(t, info.outputs["Color"], look.variation_scale, look.variation)
    straight = t.node("ShaderNodeBsdfTransparent", {"Color": _grey(t, clear)})
    paths = t.node("ShaderNodeLightPath")
    camera, glossy = paths.outputs["Is Camera Ray"], paths.outputs["Is Glossy Ray"]
    gain = t.math("ADD", t.math("MULTIPLY", camera, DAYLIGHT.film_glow - 1.0), 1.0)
    scattered = t.math("MULTIPLY", t.math("MULTIPLY", through, haze), gain)
    glow_color = t.mix_rgb(1.0, tint, _grey(t, scattered), "MULTIPLY")
    glow = t.node("ShaderNodeBsdfTranslucent", {"Color": glow_color}).outputs[0]
    glow = t.node("ShaderNodeMixShader", {0: t.math("MAXIMUM", camera, glossy),
                                          1: t.node("ShaderNodeBsdfTransparent", {"Color": (0.0, 0.0, 0.0, 1.0)}).outputs[0],
                                          2: glow}).outputs[0]
    reflect = t.node("ShaderNodeBsdfDiffuse", {"Color": t.mix_rgb(1.0, tint, (look.reflectance,) * 3, "MULTIPLY")}).outputs[0]
    surface = t.node("ShaderNodeAddShader", {0: straight.outputs[0], 1: glow}).outputs[0]
    t.output(t.node("ShaderNodeAddShader", {0: surface, 1: reflect}).outputs[0])
    return material


def pattern_material(name: str) -> bpy.types.Material:
    """The object's colour and a second one (its hue turned half round, darker) in a pattern: irregular stripes
    (wood grain, woven cloth) for an alpha under 0.5, checks (tiles, gingham) above; the alpha's place within
    its half sets the pattern's scale, 3 to 40 per metre."""
    look = MATERIALS[name]
    material, t = _new_material(name)
    info = t.node("ShaderNodeObjectInfo")
    color, alpha = info.outputs["Color"], info.outputs["Alpha"]
    checks = t.math("GREATER_THAN", alpha, 0.5)
    scale = t.map_range(t.math("FRACT", t.math("MULTIPLY", alpha, 2.0)), 0.0, 1.0, 3.0, 40.0)
    coords = t.node("ShaderNodeTexCoord").outputs["Object"]
    stripes = t.node("ShaderNodeTexWave", {"Vector": coords, "Scale": scale, "Distortion": 4.0, "Detail": 2.0}).outputs["Fac"]
    checker = t.node("ShaderNodeTexChecker", {"Vector": coords, "Scale": scale}).outputs["Fac"]
    factor = t.math("ADD", stripes, t.math("MULTIPLY", checks, t.math("SUBTRACT", checker, stripes)))
    # Hue 0.5 is no change, so 1.0 turns the hue half round
    second = t.node("ShaderNodeHueSaturation", {"Hue": 1.0, "Saturation": 1.0, "Value": 0.45, "Fac": 1.0, "Color": color})
    color = t.mix_rgb(factor, color, second.outputs[0])
    t.output(_principled(t, _varied(t, color, look.variation_scale, look.variation), look.roughness, look))
    return material


RECIPES = {"plain": plain_material, "leaf": leaf_material, "flower": flower_material, "pepper": pepper_material,
           "pepper_leaf": pepper_leaf_material, "fruit": fruit_material, "film": film_material,
           "pattern": pattern_material}


PER_VERTEX_RECIPES = {"pepper_leaf": lambda name: pepper_leaf_material(name, per_vertex=True)}


def greenhouse_materials() -> dict[str, bpy.types.Material]:
    """Every material of the table that Cycles draws, by name, built from its recipe, and the per-vertex variants
    (`per_vertex_name`) of the recipes that have one."""
    materials = {name: RECIPES[look.recipe](name) for name, look in MATERIALS.items() if look.recipe is not None}
    materials.update({per_vertex_name(name): PER_VERTEX_RECIPES[look.recipe](name)
                      for name, look in MATERIALS.items() if look.recipe in PER_VERTEX_RECIPES})
    return materials


def greenhouse_lighting(scene: bpy.types.Scene, rng: np.random.Generator, room: Sequence[float]) -> dict[str, float]:
    """Sky seen through an open (glass) roof, a sun and a soft fill from the roof, randomised.

    A gradient sky instead of a physical sky model: it costs nothing to sync and the
    walls hide the horizon anyway. The fill is one large downward area light under the
    roof, standing in for the light the whitewashed glass scatters; it is invisible to
    the camera but not to glossy rays, so it gives the peppers their broad highlights.
    Returns the drawn parameters (for logs and the report)."""
    params = {
        "sun_elevation_deg": float(rng.uniform(35.0, 75.0)),
        "sun_azimuth_deg": float(rng.uniform(0.0, 360.0)),
        "sun_strength": float(rng.uniform(2.0, 3.5)),
        "sun_angle_deg": float(rng.uniform(0.6, 4.0)),
        "sky_strength": float(rng.uniform(*SKY_STRENGTH)),  # the fifth draw: render/sky.py reads it back (SKY_DRAW)
        "fill_power": float(rng.uniform(0.6, 1.4)),
    }
    world = bpy.data.worlds.new("greenhouse_sky")
    scene.world = world
    t = _Tree(world.node_tree)
    up = t.node("ShaderNodeSeparateXYZ", {0: t.node("ShaderNodeTexCoord").outputs["Generated"]}).outputs[2]
    sky = t.mix_rgb(t.map_range(up, *SKY_RAMP, smooth=True), srgb_to_linear(SKY_HORIZON), srgb_to_linear(SKY_ZENITH))
    t.output(t.node("ShaderNodeBackground", {"Color": sky, "Strength": params["sky_strength"]}).outputs[0], "ShaderNodeOutputWorld")

    elevation, azimuth = math.radians(params["sun_elevation_deg"]), math.radians(params["sun_azimuth_deg"])
    to_sun = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation)])
    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy = params["sun_strength"]
    sun.angle = math.radians(params["sun_angle_deg"])
    sun_object = bpy.data.objects.new("sun", sun)
    pose = np.eye(4)
    pose[:3, :3] = frame_from_axis(to_sun)  # a sun light shines along its local -z
    sun_object.matrix_world = Matrix(pose.tolist())
    scene.collection.objects.link(sun_object)

    length, width, height = room
    fill = bpy.data.lights.new("roof_fill", "AREA")
    fill.shape, fill.size, fill.size_y = "RECTANGLE", float(length), float(width)
    fill.energy = params["fill_power"] * float(length) * float(width) * 2.0  # W, about fill_power W/m^2 on the floor
    fill_object = bpy.data.objects.new("roof_fill", fill)
    fill_object.location = (0.0, 0.0, float(height) - 0.01)
    fill_object.visible_camera = False
    scene.collection.objects.link(fill_object)
    return params


def _air_mass(elevation: float) -> float:
    """Relative optical path through the atmosphere towards the sun (Kasten and Young, 1989)."""
    return 1.0 / (math.sin(elevation) + 0.50572 * (math.degrees(elevation) + 6.07995) ** -1.6364)


def daylight(environment: Environment) -> dict[str, float]:
    """The film greenhouse's light from the scene's drawn hour, weather and film, in the units Cycles takes: the
    sun lamp's strength (W/m², normal to the beam), the clear sky texture's and the overcast sky's strength, and
    the irradiance of the soft light under the roof (W/m²), all scaled for the exposure (`DAYLIGHT`)."""
    d = DAYLIGHT
    film = MATERIALS["film"]
    sun = np.asarray(environment.sun, dtype=float)
    elevation = math.asin(float(np.clip(sun[2], -1.0, 1.0)))
    haze = environment.aerosol - 1.0
    air_mass = _air_mass(max(elevation, 0.0))
    beam = d.sun_normal * 0.7 ** (air_mass**0.678) * math.exp(-d.aerosol_beam * haze * air_mass)
    sky = d.sky_zenith * max(math.sin(elevation), 0.0) ** d.sky_exponent * max(1.0 + d.aerosol_sky * haze, 0.1)
    cloud = environment.cloud
    clear_global = beam * max(sun[2], 0.0) + sky
    outside = (1.0 - cloud) * clear_global + cloud * d.overcast * clear_global
    through = float(np.interp(environment.film_age, (0.0, 1.0), film.transmission))
    haze_share = float(np.interp(environment.film_age, (0.0, 1.0), film.haze))
    exposure = d.inside_irradiance / (through * outside)
    return {
        "sun_elevation": elevation,
        "sun_rotation": math.atan2(sun[0], sun[1]),  # Blender's sky: about the zenith from +y towards +x
        "sun_strength": exposure * (1.0 - cloud) * beam,
        "sky_strength": exposure * (1.0 - cloud),
        "overcast_strength": exposure * cloud * d.overcast * clear_global * 9.0 / (7.0 * math.pi),  # zenith radiance
        "fill_irradiance": d.inside_irradiance * haze_share,
        "ground_radiance": exposure * d.ground_albedo * outside / math.pi,
        "far_radiance": d.far_gain * d.inside_irradiance / math.pi,
        "exposure": exposure,
    }


def film_lighting(scene: bpy.types.Scene, environment: Environment, room: Sequence[float]) -> dict[str, float]:
    """The 'film' environment's light: Blender's Multiple Scattering sky (its sun disc off) plus an overcast sky as
    the cloud cover says, a sun lamp where the sky model's sun is, and a large soft light under the roof for the
    light the film scatters. Camera rays that leave the greenhouse or the clip range see the film's bright white,
    as a camera exposed for the crop does. Nothing is drawn here: every number comes from scene.json and the table.
    Returns the numbers (for logs and the report)."""
    params = daylight(environment)
    world = bpy.data.worlds.new("greenhouse_sky")
    world.cycles.sampling_method, world.cycles.sample_map_resolution = "MANUAL", DAYLIGHT.sky_map_resolution
    scene.world = world
    t = _Tree(world.node_tree)
    sky = t.node("ShaderNodeTexSky", sky_type="MULTIPLE_SCATTERING", sun_disc=False, sun_elevation=params["sun_elevation"],
                 sun_rotation=params["sun_rotation"], aerosol_density=max(environment.aerosol, 0.0))
    clear = t.mix_rgb(1.0, sky.outputs["Color"], (params["sky_strength"],) * 3, "MULTIPLY")
    up = t.node("ShaderNodeSeparateXYZ", {0: t.node("ShaderNodeTexCoord").outputs["Generated"]}).outputs[2]
    gradient = t.math("DIVIDE", t.math("ADD", 1.0, t.math("MULTIPLY", t.math("MAXIMUM", up, 0.0), 2.0)), 3.0)
    overcast = t.mix_rgb(1.0, srgb_to_linear(DAYLIGHT.overcast_rgb), _grey(t, t.math("MULTIPLY", gradient, params["overcast_strength"])),
                         "MULTIPLY")
    outside = t.mix_rgb(1.0, clear, overcast, "ADD")
    below = t.math("LESS_THAN", up, 0.0)
    outside = t.mix_rgb(1.0, outside, _grey(t, t.math("MULTIPLY", below, params["ground_radiance"])), "ADD")
    far = tuple(params["far_radiance"] * c for c in srgb_to_linear(film_tint(environment.film_age)))
    camera = t.node("ShaderNodeLightPath").outputs["Is Camera Ray"]
    color = t.mix_rgb(camera, outside, far)
    t.output(t.node("ShaderNodeBackground", {"Color": color, "Strength": 1.0}).outputs[0], "ShaderNodeOutputWorld")

    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy = params["sun_strength"]
    sun.angle = DAYLIGHT.sun_angle
    sun_object = bpy.data.objects.new("sun", sun)
    pose = np.eye(4)
    pose[:3, :3] = frame_from_axis(np.asarray(environment.sun, dtype=float))  # a sun light shines along its local -z
    sun_object.matrix_world = Matrix(pose.tolist())
    scene.collection.objects.link(sun_object)

    length, width, _ = room
    span_x, span_y = float(length) + 2 * environment.extent, float(width) + 2 * environment.extent
    fill = bpy.data.lights.new("roof_fill", "AREA")
    fill.shape, fill.size, fill.size_y = "RECTANGLE", span_x, span_y
    fill.energy = params["fill_irradiance"] * span_x * span_y * 2.0  # W: about fill_irradiance W/m² on the floor
    fill_object = bpy.data.objects.new("roof_fill", fill)
    fill_object.location = (0.0, 0.0, float(environment.gutter_height) - 0.01)
    fill_object.visible_camera = False
    scene.collection.objects.link(fill_object)
    return params
