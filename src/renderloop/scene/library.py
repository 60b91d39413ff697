"""A library of plant prototypes, and the scanned plants as copies of them with fruit of their own.

A commercial compartment holds thousands of plants of a few hundred leaves each: growing every one takes
minutes, and writing every leaf makes scene.json hundreds of megabytes. A greenhouse of more plants than
`plants.prototypes` therefore grows only that many plants, each with a fruit site wherever a fruit may hang
(as many a side as `plants.peppers.per_side` allows at most), and stands each of its plants as a copy of one
of them: turned by nothing or by half a turn about its axis (a half turn keeps the box and every fruit's
leaf-free window facing a side of the row), with its own fruit. Which sites carry fruit, each fruit's colour,
ripeness and size are drawn per plant from its own seed, so the fruit the pipeline counts differ from plant
to plant while the leaves and stems are shared. A fruit is scaled about its stalk end, which stays where the
prototype's peduncle ends, so it stays inside the site's bounding sphere that the prototype's leaves and
shoots keep clear of.

The library of a seed and plant config is grown once per process and reused.
"""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from renderloop.config import RIPE_COLORS, Config, PlantConfig
from renderloop.errors import UserError
from renderloop.scene.model import Box, Pepper, Plant, Prototype, copy_fruit, placement
from renderloop.scene.pepper_plant import BREAKING
from renderloop.scene.plant import PepperFitError, _round, pepper_rgb
from renderloop.scene.styles import GROWERS

__all__ = ["FRUIT_SCALE", "LIBRARY_STREAM", "YAWS", "copy_plant", "grow_library"]

LIBRARY_STREAM = 0x1B  # the library's prototypes draw from SeedSequence([seed, LIBRARY_STREAM]).spawn(prototypes)
YAWS = (0.0, math.pi)  # a copy stands as its prototype grew or turned by half a turn
FRUIT_SCALE = (0.85, 1.0)  # a copy's fruit is its site's scaled by a draw in this range (never below peppers.length)
CACHED_LIBRARIES = 4

_cache: OrderedDict[tuple, list[Prototype]] = OrderedDict()


def grow_library(config: Config, height: float) -> list[Prototype]:
    """`plants.prototypes` plants grown on a table of `height` (their pots' bases at x = y = 0), each with
    `per_side[1]` fruit sites a side; grown once per seed, plant config and height in a process."""
    plants = config.plants
    key = (config.seed, plants.model_dump_json(), round(height, 6))
    if key in _cache:
        _cache.move_to_end(key)
        return _cache[key]
    grow = GROWERS[plants.style]
    most = plants.peppers.per_side[1]
    library = []
    for index, seed in enumerate(np.random.SeedSequence([config.seed, LIBRARY_STREAM]).spawn(plants.prototypes)):
        try:
            plant, sites = grow(np.random.default_rng(seed), plants, index, -1, (0.0, 0.0, height), (most, most),
                                first_pepper_id=1)
        except PepperFitError:
            raise UserError(f"plants.peppers.per_side: {most} peppers of up to {plants.peppers.length[1]} m do not fit "
                            f"on one side of a plant of volume {list(plants.volume)} m") from None
        library.append(Prototype(plant=plant, fruit=sites))
    _cache[key] = library
    while len(_cache) > CACHED_LIBRARIES:
        _cache.popitem(last=False)
    return library


def _point(transform: np.ndarray, point) -> tuple[float, ...]:
    return _round(transform[:3, :3] @ np.asarray(point, dtype=float) + transform[:3, 3])


def copy_plant(rng: np.random.Generator, config: PlantConfig, library: list[Prototype], plant_id: int, row: int,
               position: tuple[float, float, float], peppers_per_side: tuple[int, int],
               first_pepper_id: int) -> tuple[Plant, list[Pepper]]:
    """A plant at `position` that is a copy of a prototype drawn from `library`, with `peppers_per_side` = (left,
    right) fruit on sites drawn from the prototype's, ids counting from `first_pepper_id`."""
    index = int(rng.integers(len(library)))
    prototype = library[index]
    yaw = YAWS[int(rng.integers(len(YAWS)))]
    body = prototype.plant
    pot = body.pot
    copy = Plant(id=plant_id, row=row, position=_round(np.asarray(position, dtype=float)), bearing=sum(peppers_per_side) > 0,
                 bounds=body.bounds, pot=pot, prototype=index, yaw=round(yaw, 6))
    transform = placement(copy, body)
    corners = np.array([[x, y, z] for x in (body.bounds.min[0], body.bounds.max[0])
                        for y in (body.bounds.min[1], body.bounds.max[1]) for z in (body.bounds.min[2], body.bounds.max[2])])
    moved = corners @ transform[:3, :3].T + transform[:3, 3]
    copy = copy.model_copy(update=dict(bounds=Box(min=_round(moved.min(axis=0)), max=_round(moved.max(axis=0)))))

    sites = [site.model_dump(mode="json") for site in prototype.fruit]
    across = [(transform[:3, :3] @ (np.asarray(site["center"]) - np.asarray(body.position)))[0] for site in sites]
    fruit_config = config.peppers
    names = list(fruit_config.colors)
    weights = np.array([fruit_config.colors[name] for name in names], dtype=float)
    peppers: list[Pepper] = []
    for side, count in zip(("left", "right"), peppers_per_side):
        candidates = [k for k in range(len(sites)) if (across[k] < 0) == (side == "left")]
        if count > len(candidates):  # sites are grown as many a side as per_side allows: a copy never asks for more
            raise ValueError(f"plant {plant_id}: {count} fruit on its {side} but its prototype has {len(candidates)} sites")
        for k in sorted(int(c) for c in rng.choice(len(candidates), size=count, replace=False)):
            site = sites[candidates[k]]
            color = names[int(rng.choice(len(names), p=weights / weights.sum()))]
            rgb = pepper_rgb(rng, color)
            scale = float(rng.uniform(max(FRUIT_SCALE[0], min(1.0, fruit_config.length[0] / site["length"])), FRUIT_SCALE[1]))
            breaking = rng.random() < BREAKING and color != "green"
            ripe_share = float(rng.uniform(0.55, 0.95)) if breaking else 1.0
            own = dict(id=first_pepper_id + len(peppers), plant=plant_id, site=candidates[k], scale=round(scale, 6),
                       color=color, ripe=color in RIPE_COLORS, rgb=_round(rgb),
                       ripeness=None if site.get("ripeness") is None else round(ripe_share, 6))
            peppers.append(Pepper(**copy_fruit(own, copy.position, copy.yaw, body.position, site)))
    return copy, peppers
