"""The one material table: every material of the greenhouse and the robot, by name.

Each entry holds the numbers of its Cycles recipe (built as bpy node trees in
`render/materials.py`) beside the flat colour the MuJoCo views (the raster renderer
and `world.xml`) draw it with, so changing a material is one edit here. No bpy and no
mujoco import: every view reads it.

Colours are display (sRGB) values in [0, 1], as a person picks them; Cycles converts
them to linear itself. The Cycles numbers are the reference: the shipped detector was
trained on those images. A display colour is derived from the Cycles base colour
(opaque) unless the entry sets its own: materials whose colour is the object's own
(peppers, leaves) and materials Cycles never draws (the physics canopy, the robot).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from renderloop.scene.pepper_plant import LEAF_RGB as PEPPER_LEAF_RGB
from renderloop.scene.plant import BASE_RGB, LEAF_RGB

__all__ = ["Material", "MATERIALS", "material", "display_rgba", "Daylight", "DAYLIGHT"]

RGB = tuple[float, float, float]
RGBA = tuple[float, float, float, float]
Recipe = Literal["plain", "leaf", "flower", "pepper", "pepper_leaf", "fruit", "film", "pattern"]


@dataclass(frozen=True)
class Material:
    """One material. `recipe` names the Cycles node tree (None: Cycles never draws it);
    `base_rgb` None means the recipe takes the object's own colour (object colour or the
    per-vertex leaf colour)."""

    recipe: Recipe | None
    base_rgb: RGB | None = None
    display: RGBA | None = None  # raster and MJCF colour; None: base_rgb, opaque
    roughness: float = 0.5
    metallic: float = 0.0
    specular: float | None = None  # Principled "Specular IOR Level"; None keeps Blender's default (0.5)
    coat: float = 0.0  # Principled coat weight (the wax of a fruit skin)
    coat_roughness: float = 0.03  # Blender's default, used only where coat > 0
    subsurface: float = 0.0  # Principled subsurface weight
    subsurface_scale: float | None = None  # m; None keeps Blender's default (0.05)
    sheen: float = 0.0  # Principled sheen weight (the grey bloom of a waxy leaf)
    sheen_roughness: float = 0.5
    translucency: float = 0.0  # share of a Translucent BSDF mixed in (light through leaves and petals)
    variation: float = 0.0  # blotches: the colour times a low-frequency noise in [1 - v, 1 + v]
    variation_scale: float = 5.0  # noise scale of those blotches, 1/m in object space
    roughness_range: tuple[float, float] = (1.0, 1.0)  # roughness times a noise in this range (peppers)
    roughness_scale: float = 40.0
    accent_rgb: RGB | None = None  # a second colour: the flower's centre, a leaf's dust, a turning fruit's brown
    unripe_rgb: RGB | None = None  # the green a turning fruit's skin is still in
    underside_gain: RGB = (1.0, 1.0, 1.0)  # a leaf's paler underside: its colour (linear) times this
    reticulate: float = 0.0  # the fine vein network between the lateral veins: its share of the vein colour
    blemish: float = 0.0  # share of a fruit's skin under small brown spots
    dust: float = 0.0  # how far a fully dusty leaf's colour goes to the dust's (accent) colour
    vein_gain: RGB = (1.0, 1.0, 1.0)  # leaf veins: the base colour (linear) times this
    glow_gain: RGB = (1.0, 1.0, 1.0)  # translucent light: the base colour (linear) times this
    bump: float = 0.0  # leaf vein bump strength
    transmission: tuple[float, float] = (0.0, 0.0)  # a film's share of light let through, new and at film_age 1
    haze: tuple[float, float] = (0.0, 0.0)  # the share of that light the film scatters (the rest goes straight on)
    reflectance: float = 0.0  # a film's diffuse reflection

    @property
    def rgba(self) -> RGBA:
        """The flat colour of the MuJoCo views."""
        if self.display is not None:
            return self.display
        if self.base_rgb is None:
            raise ValueError("a material without a base colour needs a display colour")
        return (*self.base_rgb, 1.0)


def _fruit(color: str, roughness: float, coat: float) -> Material:
    """The 'pepper' style's fruit skin: waxy coat over a little subsurface light, the fruit's colour turning
    from green through brown in patches (its ripe share), a few blemishes."""
    return Material("fruit", display=(*BASE_RGB[color], 1.0), roughness=roughness, coat=coat, coat_roughness=0.06,
                    specular=0.6, subsurface=0.12, subsurface_scale=0.004, variation=0.07, variation_scale=14.0,
                    roughness_range=(0.7, 1.3), roughness_scale=30.0, accent_rgb=(0.3, 0.16, 0.04),
                    unripe_rgb=BASE_RGB["green"], blemish=0.04)


def _pepper(color: str, roughness: float, coat: float) -> Material:
    """Glossy, waxy fruit skin in the colour of each fruit; ripe fruit have the glossier wax."""
    return Material("pepper", display=(*BASE_RGB[color], 1.0), roughness=roughness, coat=coat, coat_roughness=0.08,
                    specular=0.6, variation=0.08, variation_scale=18.0, roughness_range=(0.8, 1.2), roughness_scale=40.0)


MATERIALS: dict[str, Material] = {
    # the greenhouse, drawn by every view
    "leaf": Material("leaf", display=(*LEAF_RGB, 1.0), roughness=0.45, specular=0.4, translucency=0.3, variation=0.12,
                     variation_scale=30.0, vein_gain=(1.45, 1.5, 1.05), glow_gain=(1.3, 1.5, 0.8), bump=0.15),
    "flower": Material("flower", (0.96, 0.95, 0.86), roughness=0.5, translucency=0.3, accent_rgb=(0.92, 0.78, 0.2)),
    "stem": Material("plain", (0.2, 0.4, 0.1), roughness=0.5, variation=0.1, variation_scale=60.0),
    "pot": Material("plain", (0.06, 0.06, 0.065), roughness=0.55),
    "table": Material("plain", (0.55, 0.56, 0.58), roughness=0.35, metallic=0.6, variation=0.05, variation_scale=3.0),
    "workstation": Material("plain", (0.35, 0.38, 0.45), roughness=0.4, metallic=0.3),
    "floor": Material("plain", (0.5, 0.48, 0.44), roughness=0.9, variation=0.18, variation_scale=2.5),
    "wall": Material("plain", (0.86, 0.88, 0.9), roughness=0.8),
    "object_color": Material("plain", display=(0.5, 0.5, 0.5, 1.0), roughness=0.5),  # tools' meshes in their own colour
    "pepper_red": _pepper("red", 0.16, 0.35),
    "pepper_orange": _pepper("orange", 0.17, 0.35),
    "pepper_yellow": _pepper("yellow", 0.18, 0.3),
    "pepper_green": _pepper("green", 0.24, 0.2),
    # the 'pepper' plant style's own
    "pepper_leaf": Material("pepper_leaf", display=(*PEPPER_LEAF_RGB, 1.0), roughness=0.42, specular=0.5, coat=0.15,
                            coat_roughness=0.3, sheen=0.35, sheen_roughness=0.35, translucency=0.25, variation=0.14,
                            variation_scale=4.0, vein_gain=(1.7, 1.7, 1.15), glow_gain=(1.3, 1.5, 0.7),
                            underside_gain=(1.35, 1.4, 1.3), reticulate=0.4, bump=0.3, accent_rgb=(0.5, 0.52, 0.45),
                            dust=0.6),
    "calyx": Material("plain", (0.2, 0.34, 0.1), roughness=0.5, variation=0.12, variation_scale=300.0),
    "fruit_red": _fruit("red", 0.2, 0.6),
    "fruit_orange": _fruit("orange", 0.2, 0.6),
    "fruit_yellow": _fruit("yellow", 0.21, 0.55),
    "fruit_green": _fruit("green", 0.24, 0.5),
    # the 'film' environment's own (greenhouse.environment): a diffusing polyethylene film whose tint goes from
    # base_rgb (new) to accent_rgb (old) with the film's age, dirt in blotches; galvanised steel; polypropylene
    # twine; white woven ground cover; yellow sticky traps
    "film": Material("film", (0.97, 0.98, 0.97), display=(0.93, 0.94, 0.95, 1.0), accent_rgb=(0.93, 0.9, 0.74),
                     transmission=(0.88, 0.7), haze=(0.55, 0.85), reflectance=0.08, variation=0.12, variation_scale=0.4),
    "steel": Material("plain", (0.72, 0.73, 0.74), roughness=0.35, metallic=0.8, variation=0.05, variation_scale=2.0),
    "string": Material("plain", (0.86, 0.84, 0.76), roughness=0.7),
    "ground_cover": Material("plain", (0.8, 0.81, 0.79), roughness=0.85, variation=0.1, variation_scale=1.5),
    "trap": Material("plain", (0.93, 0.84, 0.08), roughness=0.25, specular=0.6),
    # the training set's clutter (dataset/clutter.py): things that are not peppers, in their object's colour
    "clutter_gloss": Material("plain", display=(0.6, 0.3, 0.2, 1.0), roughness=0.12, specular=0.6, coat=0.4,
                              variation=0.08, variation_scale=25.0),  # fruit, cans, plastic
    "clutter_matte": Material("plain", display=(0.5, 0.45, 0.35, 1.0), roughness=0.8, variation=0.25,
                              variation_scale=30.0),  # cardboard, stone, fuzzy skins
    "clutter_pattern": Material("pattern", display=(0.6, 0.5, 0.4, 1.0), roughness=0.6, variation=0.1,
                                variation_scale=8.0),  # cloth, boards, tiles: the object's colour in stripes or checks
    # the physics world's own: a plant's collision volume, shown see-through, and the robot
    "canopy": Material(None, display=(0.2, 0.55, 0.2, 0.35)),
    "uav_body": Material(None, display=(0.15, 0.15, 0.17, 1.0)),
    "uav_prop": Material(None, display=(0.8, 0.8, 0.8, 0.6)),
    "uav_arm": Material(None, display=(0.7, 0.45, 0.1, 1.0)),
    "uav_camera": Material(None, display=(0.1, 0.1, 0.1, 1.0)),
}


@dataclass(frozen=True)
class Daylight:
    """The numbers of the 'film' environment's light in Cycles (`render/materials.film_lighting`).

    The sky is Blender's Multiple Scattering sky model without its sun disc; the sun is a sun lamp in the same
    direction, which Cycles samples directly (at one sample the sky's own tiny disc would be mostly missed). The
    sky model's light is in its own units: the sun's normal irradiance and the sky's horizontal irradiance below are
    fits to it (docs/stages/render.md). An auto-exposed camera sees the crop about as bright at any hour and in any
    weather, so all light is scaled to bring the horizontal irradiance under the film to `inside_irradiance`, about
    what the 'plain' light gives; what changes with the hour and the weather is where the light comes from and its
    colour. The film lets its clear share of sun and sky straight through (Cycles follows it); the share it
    scatters reaches the crop as a large soft light under the roof, standing in for the glowing film, which only
    camera and glossy rays see, so one sample is not a lottery of light paths through the film."""

    sun_normal: float = 200.0  # the sky model's sun above the atmosphere: its beam is this times 0.7^(AM^0.678) (Meinel)
    sky_zenith: float = 17.6  # the sky model's horizontal irradiance with the sun overhead, aerosol 1
    sky_exponent: float = 0.45  # ... times sin(sun elevation) to this power
    aerosol_sky: float = 0.12  # the sky's irradiance grows by this share per unit of aerosol above 1
    aerosol_beam: float = 0.05  # optical depth of the sun's beam per unit of aerosol above 1 and per air mass
    overcast: float = 0.4  # an overcast sky's horizontal irradiance over the clear sky's (sun and sky)
    overcast_rgb: RGB = (0.78, 0.8, 0.82)  # an overcast sky's colour, brightest at the zenith (CIE overcast sky)
    sun_angle: float = 0.0093  # rad: the sun's apparent diameter
    # Cycles' importance map of the sky: the sky without its sun disc is smooth, so a coarse map samples it as well
    # as the automatic 1024 px one, whose evaluation costs seconds at every scene sync
    sky_map_resolution: int = 256
    inside_irradiance: float = 4.5  # W/m²: horizontal irradiance under the film
    # A commercial crop is a dense wall whose leaves shade one another, so a camera exposed for it sees the film far
    # brighter than the light the sparser crop here gets would make it: the film's glow, as the camera sees it, this
    # many times brighter.
    film_glow: float = 3.0
    far_gain: float = 1.1  # camera rays leaving the greenhouse (or the clip range) see film lit at this times inside_irradiance / pi
    ground_albedo: float = 0.2  # the ground outside, lit by sun and sky, seen below the horizon


DAYLIGHT = Daylight()


def material(name: str) -> Material:
    try:
        return MATERIALS[name]
    except KeyError:
        raise KeyError(f"no material {name!r} (materials: {', '.join(MATERIALS)})") from None


def display_rgba(name: str) -> RGBA:
    return material(name).rgba
