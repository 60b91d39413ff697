"""`scene.json`: the single source of truth that physics, rendering and scoring all read.

It stores the procedural description of every plant (stem polyline, leaves, flowers,
fruit shape parameters), not vertices: `renderloop.scene.plant_meshes` turns it into
the same triangle meshes for every consumer, so the file stays small and exact.
Metres, world frame ENU, z up. Pepper ids are positive (0 is background in masks)
and below 32767; the masks mark every fruit of the neighbouring rows 32767 (Blender's
object pass_index limit), a real pepper that no count asks for.

Every number is bounded, so a damaged or hand-edited file fails in `load_scene` (one line
naming the field) rather than in MuJoCo or Blender: coordinates within WORLD_BOUND of the
room's centre, sizes positive (a plant's parts at most PART_SIZE), directions unit vectors,
colours and shares in 0-1, angles within a turn either way, and every id a scene refers to
(plants, rows, prototypes, leaf templates) one that exists.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, model_validator

from renderloop.config import Config, EnvironmentConfig
from renderloop.config.fields import MAX_PLANTS, MAX_TABLES, WORLD_BOUND
from renderloop.errors import UserError, problem
from renderloop.io.atomic import write_json
from renderloop.io.bounded import field_bounds, load_json
from renderloop.rundir import names

FORMAT_VERSION = 1
MAX_PEPPER_ID = 32766
NEIGHBOUR_FRUIT_ID = 32767

# The largest part of a plant the config makes is under 2 m (a pot, a leaf, a fruit): 10 m is no plant's part.
PART_SIZE = 10.0  # m
UNIT_TOLERANCE = 1e-3  # how far from length 1 a direction may be


def _unit(vector: tuple[float, float, float]) -> tuple[float, float, float]:
    if abs(math.hypot(*vector) - 1.0) > UNIT_TOLERANCE:
        raise ValueError(f"{list(vector)} is not a unit vector")
    return vector


Coordinate = Annotated[float, Field(ge=-WORLD_BOUND, le=WORLD_BOUND)]
Vec3 = tuple[Coordinate, Coordinate, Coordinate]  # a point of the world, m
Extent = Annotated[float, Field(gt=0, le=2 * WORLD_BOUND)]  # a size of the room or of a thing in it, m
Size3 = tuple[Extent, Extent, Extent]
PartSize = Annotated[float, Field(gt=0, le=PART_SIZE)]  # a length or radius of a plant's part, m
Direction = Annotated[tuple[float, float, float], AfterValidator(_unit)]
Share = Annotated[float, Field(ge=0, le=1)]
Colour = tuple[Share, Share, Share]  # linear RGB, 0-1
Angle = Annotated[float, Field(ge=-2 * math.pi, le=2 * math.pi)]  # rad: a turn either way holds every angle
PlantId = Annotated[int, Field(ge=0, lt=MAX_PLANTS)]
RowId = Annotated[int, Field(ge=0, lt=MAX_TABLES)]
Side = Literal["left", "right"]


class Frozen(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def WhenSet(description: str | None = None, **bounds: Any) -> Any:
    """A field only some plants have (the 'pepper' style's): None by default, and then left out of the file,
    so a 'simple' scene's bytes stay what they were before the field existed."""
    return Field(None, exclude_if=lambda value: value is None, description=description, **bounds)


class Box(Frozen):
    min: Vec3
    max: Vec3

    @model_validator(mode="after")
    def _ordered(self) -> Box:
        if any(lo > hi for lo, hi in zip(self.min, self.max)):
            raise ValueError(f"min {list(self.min)} is not below max {list(self.max)}")
        return self

    def contains(self, point: Vec3, margin: float = 0.0) -> bool:
        return all(lo - margin <= p <= hi + margin for lo, p, hi in zip(self.min, point, self.max))


class Table(Frozen):
    center: Vec3
    size: Size3


class Row(Frozen):
    id: RowId
    plants: list[PlantId]
    table: Table


class Pot(Frozen):
    radius_top: PartSize
    radius_bottom: PartSize
    height: PartSize


class Tube(Frozen):
    points: list[Vec3]
    radius: PartSize


class Leaf(Frozen):
    """A blade of its own shape (`curvature`, `fold`, `twist`: the 'simple' style) or a scaled copy of a
    template (`template`: the 'pepper' style, scene/plant_meshes.LEAF_SHAPES), from `base` along `direction`."""

    base: Vec3
    direction: Direction
    up: Direction
    length: PartSize
    width: PartSize
    # 1000/m bends the blade round a 1 mm radius: tighter folds it onto itself.
    curvature: float | None = WhenSet("Bend of the midrib, 1/m.", ge=-1000, le=1000)
    fold: Angle | None = WhenSet("Both halves lifted about the midrib, rad.")
    twist: Angle | None = WhenSet("Turn of the cross-section about the midrib at the tip, rad.")
    template: int | None = WhenSet("Index of the leaf template this blade is a copy of.", ge=0)
    dust: float | None = WhenSet("Cover of a grey film of dust or residue, 0-1.", ge=0, le=1)
    rgb: Colour

    @model_validator(mode="after")
    def _one_kind(self) -> Leaf:
        own = [value is not None for value in (self.curvature, self.fold, self.twist)]
        if not (all(own) if self.template is None else not any(own)):
            raise ValueError("a leaf has either its own curvature, fold and twist or a template, not both nor neither")
        return self


class Flower(Frozen):
    center: Vec3
    normal: Direction
    radius: PartSize


class Plant(Frozen):
    id: PlantId
    row: int = Field(ge=-1, lt=MAX_TABLES, description="The row it stands in; -1: a prototype of the neighbouring rows.")
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
    # A sweet pepper's calyx has 5 to 7 sepals; each is a piece of the mesh, so their number is bounded too.
    sepals: int = Field(ge=3, le=64)
    reach: PartSize = Field(description="How far its sepals reach from the fruit's axis, m.")


class Pepper(Frozen):
    id: int = Field(ge=1, le=MAX_PEPPER_ID)
    plant: PlantId
    side: Side = Field(description="'left' is -x of its plant, 'right' is +x (facing +y along the row).")
    center: Vec3
    radius: PartSize = Field(description="Bounding-sphere radius about center.")
    color: Literal["red", "yellow", "orange", "green"]
    ripe: bool
    rgb: Colour
    length: PartSize
    width: PartSize
    lobes: int = Field(ge=0, le=12, description="Lobes of the fruit (the config draws 3 or 4).")
    # scene/meshes.pepper refuses a lobe depth of half the radius or more.
    lobe_depth: float = Field(ge=0, lt=0.5, description="Depth of the lobes over the fruit's radius.")
    axis: Direction = Field(description="Unit vector from the stalk end to the blossom end.")
    twist: Angle
    peduncle: Tube = Field(description="Stalk from the stem (first point) to the top of the fruit (last point).")
    calyx: Calyx | None = WhenSet("The calyx around the stalk end ('pepper' style).")
    ripeness: float | None = WhenSet(
        "Share of the skin in the fruit's colour; the rest is still green, with brown where the two meet (the "
        "breaker stage; 'pepper' style). Ripe or not is `color`'s.", ge=0, le=1)


class Workstation(Frozen):
    center: Vec3
    size: Size3


class Prototype(Frozen):
    """A plant of the neighbouring rows, grown once (its pot's base at x = y = 0) and stood in many places. Its fruit
    are drawn but never counted: the masks mark them NEIGHBOUR_FRUIT_ID, and they are not in the scene's `peppers`."""

    plant: Plant
    fruit: list[Pepper]


class BackgroundPlant(Frozen):
    """One plant of the neighbouring rows: a prototype turned by `yaw` about its axis and moved to `position`."""

    prototype: int = Field(ge=0)
    position: Vec3 = Field(description="Centre of the pot's base.")
    yaw: Angle = Field(description="Turn about the plant's vertical axis, rad.")


class Trap(Frozen):
    """A yellow sticky insect trap hanging above the crop, facing along `normal` (horizontal)."""

    center: Vec3
    normal: Direction


def _drawn(name: str) -> dict[str, Any]:
    """The bounds of a value drawn from the config's range `greenhouse.environment.<name>`, or set by it."""
    low, high = field_bounds(EnvironmentConfig, name)
    return {"ge": low, "le": high}


class Environment(Frozen):
    """The 'film' greenhouse round the room (config `greenhouse.environment`): what was drawn for this scene, and
    what the views build its structure from (scene/objects.py); the room is one compartment of it."""

    kind: Literal["film"]
    hour: float = Field(description="Local solar time, h.", **_drawn("hour"))
    day_of_year: int = Field(**_drawn("day_of_year"))
    sun: Direction = Field(description="Unit vector from the greenhouse to the sun, world frame (ENU).")
    cloud: float = Field(description="Cloud cover, 0-1.", **_drawn("cloud"))
    aerosol: float = Field(description="Aerosol density of the sky model.", **_drawn("aerosol"))
    film_age: float = Field(description="Age of the film, 0 (new) to 1 (old).", **_drawn("film_age"))
    extent: float = Field(description="How far the greenhouse goes on beyond the room, m.", **_drawn("extent"))
    gutter_height: float = Field(description="Height of the gutters under the film roof, m.", **_drawn("gutter_height"))
    wire_height: float = Field(description="Height of the crop wire over every row, m.", **_drawn("wire_height"))
    tables: list[Table] = Field(description="The benches (or slabs) of the neighbouring rows.")
    prototypes: list[Prototype]
    plants: list[BackgroundPlant]
    traps: list[Trap]

    @model_validator(mode="after")
    def _prototypes_exist(self) -> Environment:
        for index, plant in enumerate(self.plants):
            if plant.prototype >= len(self.prototypes):
                raise ValueError(f"environment.plants.{index}.prototype: {plant.prototype} but there are "
                                 f"{len(self.prototypes)} prototypes")
        return self


class Scene(Frozen):
    format_version: int = FORMAT_VERSION
    seed: int = Field(**dict(zip(("ge", "le"), field_bounds(Config, "seed"))))
    room: Size3
    workstation: Workstation
    rows: list[Row]
    plants: list[Plant]
    peppers: list[Pepper]
    environment: Environment | None = WhenSet("The film greenhouse round the room; none: plain walls.")

    @model_validator(mode="after")
    def _references(self) -> Scene:
        """Every id the scene refers to is one it has: a dangling one would be an IndexError deep in a stage."""
        from renderloop.scene.plant_meshes import LEAF_SHAPES  # it builds on this module: imported when first used

        rows = {row.id for row in self.rows}
        for index, plant in enumerate(self.plants):
            if plant.id != index:
                raise ValueError(f"plants.{index}.id: {plant.id}, but a plant's id is its place in the list")
            if plant.row not in rows:
                raise ValueError(f"plants.{index}.row: {plant.row} is not the id of a row")
        for index, row in enumerate(self.rows):
            missing = [plant for plant in row.plants if plant >= len(self.plants)]
            if missing:
                raise ValueError(f"rows.{index}.plants: {missing[0]} is not a plant of the scene ({len(self.plants)} plants)")
        ids = set()
        for index, pepper in enumerate(self.peppers):
            if pepper.plant >= len(self.plants):
                raise ValueError(f"peppers.{index}.plant: {pepper.plant} is not a plant of the scene ({len(self.plants)} plants)")
            if pepper.id in ids:
                raise ValueError(f"peppers.{index}.id: {pepper.id} is the id of another pepper too")
            ids.add(pepper.id)
        prototypes = self.environment.prototypes if self.environment else []
        for where, plant in [*((f"plants.{p.id}", p) for p in self.plants),
                             *((f"environment.prototypes.{i}.plant", p.plant) for i, p in enumerate(prototypes))]:
            for index, leaf in enumerate(plant.leaves):
                if leaf.template is not None and leaf.template >= len(LEAF_SHAPES):
                    raise ValueError(f"{where}.leaves.{index}.template: {leaf.template} but there are "
                                     f"{len(LEAF_SHAPES)} leaf templates")
        return self

    def plant(self, plant_id: int) -> Plant:
        return self.plants[plant_id]

    def peppers_of(self, plant_id: int) -> list[Pepper]:
        return [pepper for pepper in self.peppers if pepper.plant == plant_id]


def load_scene(path: Path) -> Scene:
    """Read and validate a `scene.json`; a broken file is a one-line UserError."""
    path = Path(path)
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: no such file (run `renderloop scene` first)") from None
    except OSError as exc:
        raise UserError(f"{path}: not a readable JSON file ({exc.__class__.__name__})") from None
    data = load_json(text, str(path))  # nesting bounded before parsing
    try:
        scene = Scene.model_validate(data)
    except ValidationError as exc:
        raise UserError(f"{path}: {problem(exc)}") from None
    if scene.format_version != FORMAT_VERSION:
        raise UserError(f"{path}: format_version {scene.format_version} is not {FORMAT_VERSION}")
    return scene


def read_scene(run_dir: Path) -> Scene:
    from renderloop.rundir import files  # the tables' readers load scipy, which training, reading scenes, does without

    files.require(run_dir, (names.SCENE,))
    return load_scene(Path(run_dir) / names.SCENE)


def write_scene(run_dir: Path, scene: Scene) -> None:
    write_json(Path(run_dir) / names.SCENE, scene.model_dump(mode="json"))
