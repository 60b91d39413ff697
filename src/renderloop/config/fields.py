"""The building blocks of the config's fields: bounded numbers, the limits that bound them, the frozen model base.

Every field is bounded above and below: the bounds let every real greenhouse and robot through and stop a typo (a
missing decimal point, a unit off by 1000) before it costs a long run or crashes a stage later.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from renderloop.errors import UserError, problem


def Real(low: float, high: float, *, low_open: bool = False, high_open: bool = False) -> Any:
    """A finite float in [low, high]; `low_open`/`high_open` leave an end out (gt/lt instead of ge/le)."""
    lower = {"gt": low} if low_open else {"ge": low}
    upper = {"lt": high} if high_open else {"le": high}
    return Annotated[float, Field(**lower, **upper, allow_inf_nan=False)]


def Count(low: int, high: int) -> Any:
    """An integer in [low, high]."""
    return Annotated[int, Field(ge=low, le=high)]


Fraction = Real(0.0, 1.0)
Angle = Real(-math.pi, math.pi)  # rad
Coordinate = Real(-100.0, 100.0)  # m: half the largest room side
Position2 = tuple[Coordinate, Coordinate]
Gain = Real(0.0, 1e5)

MAX_ROOM_SIDE = 200.0  # m
# The room's centre is the origin. No room side is longer than MAX_ROOM_SIDE and the film greenhouse
# reaches at most 50 m (`extent`) beyond it, under gutters at most 20 m high: every point of a scene the config
# makes lies within 150 m of the origin. 1000 m leaves room for a hand-built scene and still stops a unit slip
# or an overflow long before physics or rendering meets it; the run's tables (trajectory, flight, poses) share it.
WORLD_BOUND = 1000.0  # m
# The planner routes on a 5 cm occupancy grid of the whole floor: one hectare is 4 M cells, about 2 GB and
# seconds a transit; a larger floor would exhaust memory before it flew.
MAX_FLOOR_AREA = 10_000.0  # m²
MAX_TABLES = 500
MAX_PLANTS_PER_TABLE = 200
# Growing a plant takes tens of milliseconds: 5000 plants are minutes of scene
# generation, and as many ellipses for the planner, the simulation and the renderer.
MAX_PLANTS = 5000
MAX_LEAVES_PER_PLANT = 2000
# Every leaf is a mesh in scene.json and in Blender: 200 000 leaves are about 40 MB of scene and 9 M vertices.
MAX_LEAVES = 200_000
MAX_PIXELS = 8192 * 4096  # 33.5 Mpx, an 8K frame: its float RGB, depth and mask buffers alone are about 0.6 GB
MAX_CAMERA_RATE_HZ = 100.0



class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


Settings = TypeVar("Settings", bound=BaseModel)


def checked(model: type[Settings], source: str, **values: object) -> Settings:
    """`model` of `values`, or the one-line UserError the CLI prints for a config field: `source: field: problem`."""
    try:
        return model(**values)
    except ValidationError as error:
        raise UserError(f"{source}: {problem(error, model)}") from None


def ordered_range(value: tuple[float, float], name: str) -> None:
    if value[0] > value[1]:
        raise ValueError(f"{name}: minimum {value[0]} is larger than maximum {value[1]}")


def inside_room(center: tuple[float, float], size: tuple[float, ...], room: tuple[float, ...]) -> bool:
    return abs(center[0]) + size[0] / 2 <= room[0] / 2 + 1e-9 and abs(center[1]) + size[1] / 2 <= room[1] / 2 + 1e-9


def Range(low: float, high: float) -> Any:
    """A [lowest, highest] pair within [low, high]: each frame draws its value from it (equal ends: a fixed value)."""
    return tuple[Real(low, high), Real(low, high)]
