"""The function that grows a plant of each style (config `plants.style`), for the scanned plants and their
neighbours alike."""

from __future__ import annotations

from renderloop.scene.highwire import grow_highwire_plant
from renderloop.scene.pepper_plant import grow_pepper_plant
from renderloop.scene.plant import grow_plant

GROWERS = {"simple": grow_plant, "pepper": grow_pepper_plant, "highwire": grow_highwire_plant}
