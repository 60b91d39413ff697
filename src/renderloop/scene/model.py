"""`scene.json`: the single source of truth that physics, rendering and scoring all read.

It stores the procedural description of every plant (stem polyline, leaves, flowers,
fruit shape parameters), not vertices: `renderloop.scene.plant_meshes` turns it into
the same triangle meshes for every consumer, so the file stays small and exact.
Metres, world frame ENU, z up. Pepper ids are positive (0 is background in masks)
and below 32768 (Blender's object pass_index limit).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from renderloop.errors import UserError, problem

FORMAT_VERSION = 1
MAX_PEPPER_ID = 32767

Vec3 = tuple[float, float, float]
Side = Literal["left", "right"]


class Frozen(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Box(Frozen):
    min: Vec3
    max: Vec3

    def contains(self, point: Vec3, margin: float = 0.0) -> bool:
        return all(lo - margin <= p <= hi + margin for lo, p, hi in zip(self.min, point, self.max))


class Table(Frozen):
    center: Vec3
    size: Vec3


class Row(Frozen):
    id: int
    plants: list[int]
    table: Table


class Pot(Frozen):
    radius_top: float
    radius_bottom: float
    height: float


class Tube(Frozen):
    points: list[Vec3]
    radius: float


class Leaf(Frozen):
    base: Vec3
    direction: Vec3
    up: Vec3
    length: float
    width: float
    curvature: float
    fold: float
    twist: float
    rgb: Vec3


class Flower(Frozen):
    center: Vec3
    normal: Vec3
    radius: float


class Plant(Frozen):
    id: int
    row: int
    position: Vec3 = Field(description="Centre of the pot's base, on the table top.")
    bounds: Box = Field(description="Axis-aligned box holding the whole plant, pot included.")
    bearing: bool
    pot: Pot
    stem: Tube
    branches: list[Tube]
    leaves: list[Leaf]
    flowers: list[Flower]


class Pepper(Frozen):
    id: int = Field(ge=1, le=MAX_PEPPER_ID)
    plant: int
    side: Side = Field(description="'left' is -x of its plant, 'right' is +x (facing +y along the row).")
    center: Vec3
    radius: float = Field(gt=0, description="Bounding-sphere radius about center.")
    color: Literal["red", "yellow", "orange", "green"]
    ripe: bool
    rgb: Vec3
    length: float
    width: float
    lobes: int
    lobe_depth: float
    axis: Vec3 = Field(description="Unit vector from the stalk end to the blossom end.")
    twist: float
    peduncle: Tube = Field(description="Stalk from the stem (first point) to the top of the fruit (last point).")


class Workstation(Frozen):
    center: Vec3
    size: Vec3


class Scene(Frozen):
    format_version: int = FORMAT_VERSION
    seed: int
    room: Vec3
    workstation: Workstation
    rows: list[Row]
    plants: list[Plant]
    peppers: list[Pepper]

    def plant(self, plant_id: int) -> Plant:
        return self.plants[plant_id]

    def peppers_of(self, plant_id: int) -> list[Pepper]:
        return [pepper for pepper in self.peppers if pepper.plant == plant_id]


def load_scene(path: Path) -> Scene:
    """Read and validate a `scene.json`; a broken file is a one-line UserError."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{path}: no such file (run `renderloop scene` first)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UserError(f"{path}: not a readable JSON file ({exc.__class__.__name__})") from None
    try:
        scene = Scene.model_validate(data)
    except ValidationError as exc:
        raise UserError(f"{path}: {problem(exc)}") from None
    if scene.format_version != FORMAT_VERSION:
        raise UserError(f"{path}: format_version {scene.format_version} is not {FORMAT_VERSION}")
    return scene
