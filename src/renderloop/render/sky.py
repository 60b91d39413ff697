"""What a camera ray that meets nothing in the clip range sees: Cycles' world colour, for the raster view.

Cycles ends a camera ray at the far clip and shows the world there, so its frames have sky wherever the
greenhouse is farther than `camera.clip`; the raster view, whose OpenGL clears to black, paints the same colour
behind its geometry (`render/raster.py`). The numbers are those the Cycles world is built from
(`render/materials.py`: `greenhouse_lighting` for the plain room, `film_lighting` for the film greenhouse):

- the plain room's gradient sky, from a pale horizon to a blue zenith along the ray's world z, times the sky
  strength its lighting draws from the scene's seed;
- the film greenhouse, whose camera rays see the film's glow, one colour: the film's tint (its age) at
  `DAYLIGHT.far_gain` times the irradiance under the film, over pi.

Colours go through the sRGB OETF and 8-bit quantisation as Cycles' Combined pass does (`render/srgb.py`).
Numpy only, so the raster process never imports bpy; `tests/test_raster_view.py` checks these colours against
Cycles' own sky pixels and its drawn sky strength.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderloop.render.srgb import encode_u8, to_linear
from renderloop.scene.materials import DAYLIGHT
from renderloop.scene.model import Scene
from renderloop.scene.objects import film_tint

__all__ = ["LIGHTING_STREAM", "SKY_HORIZON", "SKY_RAMP", "SKY_ZENITH", "Sky", "plain_sky_strength",
           "scene_sky"]

LIGHTING_STREAM = 0xC7  # the plain room's light: SeedSequence([scene.seed, LIGHTING_STREAM]), as Cycles draws it
SKY_HORIZON = (0.86, 0.9, 0.95)  # sRGB: the plain sky at and below the horizon
SKY_ZENITH = (0.45, 0.62, 0.9)  # sRGB: the plain sky from SKY_RAMP[1] of the way up
SKY_RAMP = (-0.05, 0.7)  # the ray's world z over which the plain sky goes from horizon to zenith (smoothstep)
SKY_STRENGTH = (0.6, 1.1)  # the range the plain sky's strength is drawn from
SKY_DRAW = 4  # draws of the lighting stream before the sky strength (the sun's elevation, azimuth, strength, angle)


def plain_sky_strength(seed: int) -> float:
    """The plain room's sky strength as its Cycles lighting draws it: the fifth uniform of the lighting stream."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, LIGHTING_STREAM]))
    rng.uniform(size=SKY_DRAW)
    return float(rng.uniform(*SKY_STRENGTH))


@dataclass(frozen=True)
class Sky:
    """The world colour of one scene: a gradient along the ray's world z (`zenith` set) or one colour."""

    horizon: tuple[float, float, float]  # linear, strength included
    zenith: tuple[float, float, float] | None = None  # linear, strength included; None: one colour

    @property
    def uniform(self) -> bool:
        return self.zenith is None

    def colour(self, up: np.ndarray | float = 0.0) -> np.ndarray:
        """8-bit sRGB colour of rays whose unit direction has world z `up` (any shape; (..., 3) out)."""
        up = np.asarray(up, dtype=np.float64)
        horizon = np.asarray(self.horizon)
        if self.zenith is None:
            return np.broadcast_to(encode_u8(horizon), (*up.shape, 3)).copy()
        low, high = SKY_RAMP
        t = np.clip((up - low) / (high - low), 0.0, 1.0)
        t = t * t * (3.0 - 2.0 * t)  # Blender's Map Range SMOOTHSTEP
        linear = horizon + t[..., None] * (np.asarray(self.zenith) - horizon)
        return encode_u8(linear)


def scene_sky(scene: Scene) -> Sky:
    """The world colour Cycles gives the scene's camera rays: the plain room's sky, or the film greenhouse's glow."""
    environment = scene.environment
    if environment is None:
        strength = plain_sky_strength(scene.seed)
        return Sky(tuple(strength * to_linear(SKY_HORIZON)), tuple(strength * to_linear(SKY_ZENITH)))
    radiance = DAYLIGHT.far_gain * DAYLIGHT.inside_irradiance / math.pi
    return Sky(tuple(radiance * to_linear(film_tint(environment.film_age))))
