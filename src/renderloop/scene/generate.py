"""Build a whole greenhouse scene from a config: layout, which plants bear, how many fruit, the plants (each grown in
its place, or with more plants than `plants.prototypes` each a copy of a prototype: scene/library.py).

Each plant draws from its own child of the run's SeedSequence, so changing one
plant's parameters does not reshuffle every plant after it, and the same seed
always gives the same scene.
"""

from __future__ import annotations

import numpy as np

from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.scene.environment import draw_environment
from renderloop.scene.layout import table_slots
from renderloop.scene.library import copy_plant, grow_library
from renderloop.scene.model import MAX_PEPPER_ID, Row, Scene, Table, Workstation
from renderloop.scene.plant import PepperFitError
from renderloop.scene.styles import GROWERS


def _bearing_plants(rng: np.random.Generator, total: int, bearing: int | None) -> set[int]:
    if bearing is None:
        return set(range(total))
    return {int(i) for i in rng.choice(total, size=bearing, replace=False)}


def generate_scene(config: Config) -> Scene:
    greenhouse, plants_config = config.greenhouse, config.plants
    slots = table_slots(greenhouse)
    total = sum(len(slot.plant_positions) for slot in slots)
    layout_seed, *plant_seeds = np.random.SeedSequence(config.seed).spawn(total + 1)
    layout_rng = np.random.default_rng(layout_seed)
    bearing = _bearing_plants(layout_rng, total, plants_config.bearing)
    low, high = plants_config.peppers.per_side
    per_side = {
        plant_id: (int(layout_rng.integers(low, high + 1)), int(layout_rng.integers(low, high + 1)))
        for plant_id in sorted(bearing)
    }
    if sum(left + right for left, right in per_side.values()) > MAX_PEPPER_ID:
        raise UserError(f"plants.peppers.per_side: more than {MAX_PEPPER_ID} peppers in one scene")

    grow = GROWERS[plants_config.style]
    # More plants than the library holds: each is a copy of a prototype with fruit of its own (scene/library.py)
    library = grow_library(config, greenhouse.table_size[2]) if total > plants_config.prototypes else None
    rows, plants, peppers = [], [], []
    for slot in slots:
        plant_ids = []
        for position in slot.plant_positions:
            plant_id = len(plants)
            rng = np.random.default_rng(plant_seeds[plant_id])
            try:
                if library is not None:
                    plant, fruit = copy_plant(rng, plants_config, library, plant_id, slot.row, position,
                                              per_side.get(plant_id, (0, 0)), first_pepper_id=len(peppers) + 1)
                else:
                    plant, fruit = grow(rng, plants_config, plant_id, slot.row, position,
                                        per_side.get(plant_id, (0, 0)), first_pepper_id=len(peppers) + 1)
            except PepperFitError:
                raise UserError(
                    f"plants.peppers.per_side: up to {high} peppers of up to {plants_config.peppers.length[1]} m "
                    f"do not fit on one side of a plant of volume {list(plants_config.volume)} m"
                ) from None
            plants.append(plant)
            peppers.extend(fruit)
            plant_ids.append(plant_id)
        rows.append(Row(id=slot.row, plants=plant_ids, table=Table(center=slot.center, size=slot.size)))

    station_size = greenhouse.workstation_size
    film = greenhouse.environment.kind == "film"
    return Scene(
        seed=config.seed,
        room=greenhouse.size,
        workstation=Workstation(center=(*greenhouse.workstation_center, station_size[2] / 2), size=station_size),
        rows=rows,
        plants=plants,
        peppers=peppers,
        prototypes=library,
        environment=draw_environment(config, rows, plants, library) if film else None,
    )
