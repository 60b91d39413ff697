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
is one object and one material, which keeps Cycles' scene sync short.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import bpy
import numpy as np
from mathutils import Matrix

from renderloop.scene.materials import MATERIALS, Material
from renderloop.scene.meshes import frame_from_axis

LEAF_COLOR_ATTRIBUTE = "leaf_rgb"


def srgb_to_linear_array(rgb: np.ndarray) -> np.ndarray:
    """sRGB display values in [0, 1] (any shape) to the linear values Cycles shades with."""
    c = np.clip(np.asarray(rgb, dtype=float), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def srgb_to_linear(rgb: Sequence[float]) -> tuple[float, float, float]:
    lin = srgb_to_linear_array(np.asarray(rgb, dtype=float)[:3])
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
    values.update(inputs)
    return t.node("ShaderNodeBsdfPrincipled", values).outputs[0]


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


RECIPES = {"plain": plain_material, "leaf": leaf_material, "flower": flower_material, "pepper": pepper_material}


def greenhouse_materials() -> dict[str, bpy.types.Material]:
    """Every material of the table that Cycles draws, by name, built from its recipe."""
    return {name: RECIPES[look.recipe](name) for name, look in MATERIALS.items() if look.recipe is not None}


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
        "sky_strength": float(rng.uniform(0.6, 1.1)),
        "fill_power": float(rng.uniform(0.6, 1.4)),
    }
    world = bpy.data.worlds.new("greenhouse_sky")
    scene.world = world
    t = _Tree(world.node_tree)
    up = t.node("ShaderNodeSeparateXYZ", {0: t.node("ShaderNodeTexCoord").outputs["Generated"]}).outputs[2]
    sky = t.mix_rgb(t.map_range(up, -0.05, 0.7, smooth=True), srgb_to_linear((0.86, 0.9, 0.95)), srgb_to_linear((0.45, 0.62, 0.9)))
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
