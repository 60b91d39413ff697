"""The function that grows a plant of each style (config `plants.style`), for the scanned plants and their
neighbours alike: grow(rng, plant config, plant id, row, position, (left, right) fruit, first fruit id)."""

from __future__ import annotations

from functools import partial

from renderloop.scene.highwire import HighWireGrower
from renderloop.scene.pepper_plant import grow_pepper_plant
from renderloop.scene.plant import grow_plant

GROWERS = {"simple": grow_plant, "pepper": grow_pepper_plant,
           "highwire": partial(grow_pepper_plant, grower_class=HighWireGrower)}
