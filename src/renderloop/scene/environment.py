"""The film greenhouse round the room, drawn once per scene (`greenhouse.environment.kind: film`).

The room is one compartment of a larger greenhouse: its crop goes on beyond the room's walls
(which stay in the physics world as the flight volume's fence, and are not drawn), in
neighbouring rows at `row_pitch` beyond the walls across the rows and in the scanned rows'
own lines beyond their ends, each on a bench like the scanned rows' and up to `extent` from
the room, where the film walls stand. What is drawn here goes into scene.json: the time of
day and the sun, the sky and film numbers, the benches, a few prototype plants grown with the
scene's own plant config, where each neighbouring plant stands (a prototype turned about
its axis) and the sticky traps. The structure itself (film, gutters, posts, trusses, wires,
strings) has no random part: `scene/objects.py` builds it from these numbers.

Every draw comes from the environment's own stream of the run's seed, so a 'film' scene
grows the same scanned plants, with the same fruit, as a 'plain' one.
"""

from __future__ import annotations

import math

import numpy as np

from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.scene.model import BackgroundPlant, Environment, Plant, Prototype, Row, Table, Trap
from renderloop.scene.objects import CHORD, GUTTER, TRUSS_DEPTH
from renderloop.scene.plant import PepperFitError
from renderloop.scene.styles import GROWERS

__all__ = ["ENVIRONMENT_STREAM", "PROTOTYPES", "draw_environment", "sun_direction"]

ENVIRONMENT_STREAM = 0xE1  # the environment's generator is SeedSequence([seed, ENVIRONMENT_STREAM])
PROTOTYPES = 4  # distinct neighbouring plants; each is stood in many places, turned
MIN_SUN_ELEVATION = 0.09  # rad: lower, the film lets almost nothing of the sun through
FENCE_GAP = 0.05  # m between the room's wall and the nearest neighbouring plant or bench
OBLIQUITY = 0.4091  # rad: the tilt of the Earth's axis, the sun's largest declination
TRAP_LIFT = (0.05, 0.35)  # m above the plant's top its trap hangs
# The scanned plants stand greenhouse.plant_spacing apart so that their boxes do not overlap (the counting assigns
# fruit to plants by box); a commercial row is a continuous wall of plants, and the neighbouring rows, counted by
# no one, are planted that densely.
NEIGHBOUR_SPACING = 0.5  # of greenhouse.plant_spacing
TRAPS_PER_METRE = 0.5  # yellow sticky traps per metre of neighbouring row at clutter 1


def _declination(day: int) -> float:
    """The sun's declination on a day of the year (a cosine through the solstices, within 0.01 rad)."""
    return -OBLIQUITY * math.cos(2 * math.pi * (day + 10) / 365)


def sun_direction(hour: float, day: int, latitude: float) -> np.ndarray:
    """Unit vector from the greenhouse to the sun (ENU: x east, y north, z up) at local solar time `hour`."""
    declination = _declination(day)
    hour_angle = (hour - 12.0) * math.pi / 12.0
    # the sun in an equatorial frame turned to the local horizon: east, north, up
    east = -math.cos(declination) * math.sin(hour_angle)
    north = math.sin(declination) * math.cos(latitude) - math.cos(declination) * math.cos(hour_angle) * math.sin(latitude)
    up = math.sin(declination) * math.sin(latitude) + math.cos(declination) * math.cos(hour_angle) * math.cos(latitude)
    return np.array([east, north, up])


def _daylight_hour(hour: float, day: int, latitude: float) -> float:
    """`hour`, or the nearest time that day when the sun stands MIN_SUN_ELEVATION high (noon if it never does)."""
    declination = _declination(day)
    cos_limit = (math.sin(MIN_SUN_ELEVATION) - math.sin(latitude) * math.sin(declination)) / (
        math.cos(latitude) * math.cos(declination))
    if cos_limit <= -1.0:  # the sun never sets that low
        return hour
    half_day = math.acos(min(cos_limit, 1.0)) * 12.0 / math.pi
    return float(np.clip(hour, 12.0 - half_day, 12.0 + half_day))


def _positions(start: float, end: float, spacing: float) -> np.ndarray:
    """Plant positions along a line from `start` to `end`, `spacing` apart and centred between them."""
    if end < start:
        return np.zeros(0)
    count = int(math.floor((end - start) / spacing + 1e-9)) + 1
    return (start + end) / 2 + (np.arange(count) - (count - 1) / 2) * spacing


def _lines(config: Config, rows: list[Row], reach: float) -> list[tuple[float, float, float]]:
    """The neighbouring rows as (x, y_start, y_end) of their plants' axes: whole rows beyond the room's walls across
    the rows, and the scanned rows' own lines beyond the room's ends. `reach` is how far a plant or its bench
    reaches from its axis."""
    greenhouse, environment = config.greenhouse, config.greenhouse.environment
    length, width, _ = greenhouse.size
    half_x, half_y = length / 2 + environment.extent, width / 2 + environment.extent
    lines = []
    x = length / 2 + FENCE_GAP + reach
    while x + reach <= half_x + 1e-9:
        lines += [(-x, -half_y + reach, half_y - reach), (x, -half_y + reach, half_y - reach)]
        x += environment.row_pitch
    for x in sorted({row.table.center[0] for row in rows}):
        start = width / 2 + FENCE_GAP + reach
        if half_y - reach >= start:
            lines += [(x, -half_y + reach, -start), (x, start, half_y - reach)]
    return lines


def _prototypes(rng: np.random.Generator, config: Config, height: float) -> list[Prototype]:
    grow = GROWERS[config.plants.style]
    low, high = config.plants.peppers.per_side
    seeds = np.random.SeedSequence(int(rng.integers(2**63))).spawn(PROTOTYPES)
    prototypes = []
    for index, seed in enumerate(seeds):
        plant_rng = np.random.default_rng(seed)
        per_side = (int(plant_rng.integers(low, high + 1)), int(plant_rng.integers(low, high + 1)))
        try:
            plant, fruit = grow(plant_rng, config.plants, index, -1, (0.0, 0.0, height), per_side, first_pepper_id=1)
        except PepperFitError:
            raise UserError(f"plants.peppers.per_side: up to {high} peppers do not fit on one side of a plant of volume "
                            f"{list(config.plants.volume)} m") from None
        prototypes.append(Prototype(plant=plant, fruit=fruit))
    return prototypes


def _round(values: np.ndarray) -> tuple[float, ...]:
    return tuple(round(float(v), 6) for v in values)


def draw_environment(config: Config, rows: list[Row], plants: list[Plant],
                     library: list[Prototype] | None = None) -> Environment:
    """The film greenhouse round the room of a scene whose scanned rows and plants are `rows` and `plants`; with a
    `library` of plant prototypes (scene/library.py), its first PROTOTYPES stand in the neighbouring rows too, so
    scene.json holds them once and no more plants are grown."""
    greenhouse, settings = config.greenhouse, config.greenhouse.environment
    rng = np.random.default_rng(np.random.SeedSequence([config.seed, ENVIRONMENT_STREAM]))
    day = int(rng.integers(settings.day_of_year[0], settings.day_of_year[1] + 1))
    hour = _daylight_hour(float(rng.uniform(*settings.hour)), day, settings.latitude)
    cloud, aerosol, film_age, clutter = (float(rng.uniform(*getattr(settings, name)))
                                         for name in ("cloud", "aerosol", "film_age", "clutter"))
    sun = sun_direction(hour, day, settings.latitude)

    lowest = settings.gutter_height - GUTTER[1] - TRUSS_DEPTH - CHORD / 2
    if lowest < greenhouse.size[2]:
        raise UserError(f"greenhouse.environment.gutter_height: the trusses under gutters at {settings.gutter_height} m "
                        f"reach down to {lowest:.2f} m, into the {greenhouse.size[2]} m high room")
    bench_width, _, bench_height = greenhouse.table_size
    shared = min(PROTOTYPES, len(library)) if library else None
    prototypes = library[:shared] if shared else _prototypes(rng, config, bench_height)
    tops = [plant.bounds.max[2] for plant in plants] + [p.plant.bounds.max[2] for p in prototypes]
    if max(tops) >= settings.wire_height:
        raise UserError(f"greenhouse.environment.wire_height: the crop wire at {settings.wire_height} m is not above "
                        f"the plants' tops ({max(tops):.2f} m)")
    reach = max(bench_width / 2, max(math.hypot(*np.abs(p.plant.bounds.min[:2]) + np.abs(p.plant.bounds.max[:2])) / 2
                                     for p in prototypes))
    tables, background, traps = [], [], []
    for x, start, end in _lines(config, rows, reach):
        spacing = NEIGHBOUR_SPACING * greenhouse.plant_spacing
        ys = _positions(start, end, spacing)
        if not len(ys):
            continue
        ends = (ys[0] - spacing / 2, ys[-1] + spacing / 2)
        tables.append(Table(center=_round(np.array([x, sum(ends) / 2, bench_height / 2])),
                            size=_round(np.array([bench_width, ends[1] - ends[0], bench_height]))))
        for y in ys:
            prototype = int(rng.integers(len(prototypes)))
            background.append(BackgroundPlant(prototype=prototype, position=_round(np.array([x, y, bench_height])),
                                              yaw=round(float(rng.uniform(0.0, 2 * math.pi)), 6)))
            if rng.random() < clutter * TRAPS_PER_METRE * spacing:
                facing = 1.0 if x < 0 else -1.0  # towards the room, where the cameras are
                top = prototypes[prototype].plant.bounds.max[2]
                center = np.array([x + facing * 0.1, y + rng.uniform(-0.2, 0.2), top + rng.uniform(*TRAP_LIFT)])
                traps.append(Trap(center=_round(center), normal=(facing, 0.0, 0.0)))
    return Environment(
        kind="film", hour=round(hour, 6), day_of_year=day, sun=_round(sun), cloud=round(cloud, 6),
        aerosol=round(aerosol, 6), film_age=round(film_age, 6), extent=settings.extent,
        gutter_height=settings.gutter_height, wire_height=settings.wire_height,
        tables=tables, prototypes=prototypes, plants=background, traps=traps, shared=shared,
    )
