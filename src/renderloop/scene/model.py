"""`scene.json`: the single source of truth that physics, rendering and scoring all read.

It stores the procedural description of every plant (stem polyline, leaves, flowers,
fruit shape parameters), not vertices: `renderloop.scene.plant_meshes` turns it into
the same triangle meshes for every consumer, so the file stays small and exact.
Metres, world frame ENU, z up. Pepper ids are positive (0 is background in masks)
and below 32767; the masks mark every fruit of the neighbouring rows 32767 (Blender's
object pass_index limit), a real pepper that no count asks for.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from renderloop.errors import UserError, problem

FORMAT_VERSION = 1
MAX_PEPPER_ID = 32766
NEIGHBOUR_FRUIT_ID = 32767

Vec3 = tuple[float, float, float]
Side = Literal["left", "right"]


class Frozen(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def WhenSet(description: str | None = None, **bounds: Any) -> Any:
    """A field only some plants have (the 'pepper' style's): None by default, and then left out of the file,
    so a 'simple' scene's bytes stay what they were before the field existed."""
    return Field(None, exclude_if=lambda value: value is None, description=description, **bounds)


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
    """A blade of its own shape (`curvature`, `fold`, `twist`: the 'simple' style) or a scaled copy of a
    template (`template`: the 'pepper' style, scene/plant_meshes.LEAF_SHAPES), from `base` along `direction`."""

    base: Vec3
    direction: Vec3
    up: Vec3
    length: float
    width: float
    curvature: float | None = WhenSet("Bend of the midrib, 1/m.")
    fold: float | None = WhenSet("Both halves lifted about the midrib, rad.")
    twist: float | None = WhenSet("Turn of the cross-section about the midrib at the tip, rad.")
    template: int | None = WhenSet("Index of the leaf template this blade is a copy of.", ge=0)
    dust: float | None = WhenSet("Cover of a grey film of dust or residue, 0-1.", ge=0, le=1)
    rgb: Vec3

    @model_validator(mode="after")
    def _one_kind(self) -> Leaf:
        own = [value is not None for value in (self.curvature, self.fold, self.twist)]
        if not (all(own) if self.template is None else not any(own)):
            raise ValueError("a leaf has either its own curvature, fold and twist or a template, not both nor neither")
        return self


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
    strings: list[Vec3] | None = WhenSet("Where each stem's string is tied at the plant's foot (the 'highwire' "
                                         "style); a string runs straight up from there to the crop wire.")


class Calyx(Frozen):
    sepals: int = Field(ge=3)
    reach: float = Field(gt=0, description="How far its sepals reach from the fruit's axis, m.")


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
    calyx: Calyx | None = WhenSet("The calyx around the stalk end ('pepper' style).")
    ripeness: float | None = WhenSet(
        "Share of the skin in the fruit's colour; the rest is still green, with brown where the two meet (the "
        "breaker stage; 'pepper' style). Ripe or not is `color`'s.", ge=0, le=1)


class Workstation(Frozen):
    center: Vec3
    size: Vec3


class Prototype(Frozen):
    """A plant of the neighbouring rows, grown once (its pot's base at x = y = 0) and stood in many places. Its fruit
    are drawn but never counted: the masks mark them NEIGHBOUR_FRUIT_ID, and they are not in the scene's `peppers`."""

    plant: Plant
    fruit: list[Pepper]


class BackgroundPlant(Frozen):
    """One plant of the neighbouring rows: a prototype turned by `yaw` about its axis and moved to `position`."""

    prototype: int = Field(ge=0)
    position: Vec3 = Field(description="Centre of the pot's base.")
    yaw: float = Field(description="Turn about the plant's vertical axis, rad.")


class Trap(Frozen):
    """A yellow sticky insect trap hanging above the crop, facing along `normal` (horizontal)."""

    center: Vec3
    normal: Vec3


class Environment(Frozen):
    """The 'film' greenhouse round the room (config `greenhouse.environment`): what was drawn for this scene, and
    what the views build its structure from (scene/objects.py); the room is one compartment of it."""

    kind: Literal["film"]
    hour: float = Field(description="Local solar time, h.")
    day_of_year: int
    sun: Vec3 = Field(description="Unit vector from the greenhouse to the sun, world frame (ENU).")
    cloud: float = Field(ge=0, le=1, description="Cloud cover, 0-1.")
    aerosol: float = Field(ge=0, description="Aerosol density of the sky model.")
    film_age: float = Field(ge=0, le=1, description="Age of the film, 0 (new) to 1 (old).")
    extent: float = Field(ge=0, description="How far the greenhouse goes on beyond the room, m.")
    gutter_height: float = Field(gt=0, description="Height of the gutters under the film roof, m.")
    wire_height: float = Field(gt=0, description="Height of the crop wire over every row, m.")
    tables: list[Table] = Field(description="The benches (or slabs) of the neighbouring rows.")
    prototypes: list[Prototype]
    plants: list[BackgroundPlant]
    traps: list[Trap]


class Scene(Frozen):
    format_version: int = FORMAT_VERSION
    seed: int
    room: Vec3
    workstation: Workstation
    rows: list[Row]
    plants: list[Plant]
    peppers: list[Pepper]
    environment: Environment | None = WhenSet("The film greenhouse round the room; none: plain walls.")

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
