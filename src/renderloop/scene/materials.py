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

from renderloop.scene.plant import BASE_RGB, LEAF_RGB

__all__ = ["Material", "MATERIALS", "material", "display_rgba"]

RGB = tuple[float, float, float]
RGBA = tuple[float, float, float, float]
Recipe = Literal["plain", "leaf", "flower", "pepper"]


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
    translucency: float = 0.0  # share of a Translucent BSDF mixed in (light through leaves and petals)
    variation: float = 0.0  # blotches: the colour times a low-frequency noise in [1 - v, 1 + v]
    variation_scale: float = 5.0  # noise scale of those blotches, 1/m in object space
    roughness_range: tuple[float, float] = (1.0, 1.0)  # roughness times a noise in this range (peppers)
    roughness_scale: float = 40.0
    accent_rgb: RGB | None = None  # a second colour: the flower's centre
    vein_gain: RGB = (1.0, 1.0, 1.0)  # leaf veins: the base colour (linear) times this
    glow_gain: RGB = (1.0, 1.0, 1.0)  # translucent light: the base colour (linear) times this
    bump: float = 0.0  # leaf vein bump strength

    @property
    def rgba(self) -> RGBA:
        """The flat colour of the MuJoCo views."""
        if self.display is not None:
            return self.display
        if self.base_rgb is None:
            raise ValueError("a material without a base colour needs a display colour")
        return (*self.base_rgb, 1.0)


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
    # the physics world's own: a plant's collision volume, shown see-through, and the robot
    "canopy": Material(None, display=(0.2, 0.55, 0.2, 0.35)),
    "uav_body": Material(None, display=(0.15, 0.15, 0.17, 1.0)),
    "uav_prop": Material(None, display=(0.8, 0.8, 0.8, 0.6)),
    "uav_arm": Material(None, display=(0.7, 0.45, 0.1, 1.0)),
    "uav_camera": Material(None, display=(0.1, 0.1, 0.1, 1.0)),
}


def material(name: str) -> Material:
    try:
        return MATERIALS[name]
    except KeyError:
        raise KeyError(f"no material {name!r} (materials: {', '.join(MATERIALS)})") from None


def display_rgba(name: str) -> RGBA:
    return material(name).rgba
