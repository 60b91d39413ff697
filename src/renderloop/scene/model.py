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
from collections.abc import Iterable
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, model_serializer, model_validator

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


BODY = ("stem", "branches", "leaves", "flowers", "strings")  # what a copy of a prototype takes from it, not the file


class Plant(Frozen):
    """A plant grown in its place, or (`prototype` set) a copy of one of the scene's prototypes, turned by `yaw`
    about its axis and stood at `position`: its body (stem, branches, leaves, flowers, strings) is the prototype's,
    its fruit its own (the scene's `peppers`), so scene.json holds a prototype's leaves once however many copies
    stand in the rows."""

    id: PlantId
    row: int = Field(ge=-1, lt=MAX_TABLES, description="The row it stands in; -1: a prototype of the neighbouring rows.")
    position: Vec3 = Field(description="Centre of the pot's base, on the table top.")
    bounds: Box = Field(description="Axis-aligned box holding the whole plant, pot included.")
    bearing: bool
    pot: Pot
    stem: Tube | None = WhenSet("The main stem; a copy of a prototype has its prototype's.")
    branches: list[Tube] = Field(default_factory=list)
    leaves: list[Leaf] = Field(default_factory=list)
    flowers: list[Flower] = Field(default_factory=list)
    strings: list[Vec3] | None = WhenSet("Where each stem's string is tied at the plant's foot (the 'highwire' "
                                         "style); a string runs straight up from there to the crop wire.")
    prototype: int | None = WhenSet("Index in the scene's `prototypes` of the plant this one is a copy of.", ge=0)
    yaw: Angle | None = WhenSet("A copy's turn about its vertical axis from its prototype, rad.")

    @model_validator(mode="after")
    def _body(self) -> Plant:
        if self.prototype is None:
            if self.stem is None:
                raise ValueError("a plant that is no copy of a prototype needs its stem")
        elif self.yaw is None or any(getattr(self, name) for name in BODY):
            raise ValueError("a copy of a prototype has a yaw and takes its stem, branches, leaves, flowers and "
                             "strings from the prototype")
        return self

    @model_serializer(mode="wrap")
    def _dump(self, handler: Any) -> dict[str, Any]:
        data = handler(self)
        if self.prototype is not None:  # a copy's body is its prototype's: the file names it, never repeats it
            for name in BODY:
                data.pop(name, None)
        return data

    @property
    def is_copy(self) -> bool:
        return self.prototype is not None


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
    site: int | None = WhenSet("A copy's fruit: the index of the fruit site of its plant's prototype it hangs on; "
                               "scene.json then keeps only its own draws (COPY_FRUIT), the rest follows from the site.",
                               ge=0)
    # at most 1: a fruit scaled about its stalk end stays inside the site's bounding sphere, which the leaves keep clear of
    scale: float | None = WhenSet("A copy's fruit: its size over its site's, scaled about the stalk end.", gt=0, le=1)


# What scene.json keeps of a copy's fruit: its id and its own draws; `copy_fruit` rebuilds the rest from the site.
COPY_FRUIT = ("id", "plant", "site", "scale", "color", "ripe", "rgb", "ripeness")


def copy_fruit(compact: dict[str, Any], position: Any, yaw: float, origin: Any, site: dict[str, Any]) -> dict[str, Any]:
    """The whole record of a copy's fruit from its own draws (`compact`, the COPY_FRUIT fields) and the prototype's
    site it hangs on (a Pepper's fields in the prototype's frame, whose pot's base is at `origin`), for a copy turned
    by `yaw` and stood at `position`: the generator and the reader both build a copy's fruit here, so a scene read
    back is the scene written. Scaling about the stalk end keeps the site's peduncle as it is."""
    transform = _placement(position, yaw, origin)
    rotation, shift = transform[:3, :3], transform[:3, 3]

    def moved(point: Any) -> tuple[float, ...]:
        return tuple(round(float(v), 6) for v in rotation @ np.asarray(point, dtype=float) + shift)

    scale = float(compact["scale"])
    site_center = np.asarray(site["center"], dtype=float)
    stalk_end = np.asarray(site["peduncle"]["points"][-1], dtype=float)
    across = (rotation @ (site_center - np.asarray(origin, dtype=float)))[0]
    calyx = site.get("calyx")
    return {
        **compact,
        "side": "left" if across < 0 else "right",
        "center": moved(stalk_end + scale * (site_center - stalk_end)),
        "radius": math.ceil(float(site["radius"]) * scale * 1e6) / 1e6 + 2e-6,
        "length": round(float(site["length"]) * scale, 6),
        "width": round(float(site["width"]) * scale, 6),
        "lobes": site["lobes"],
        "lobe_depth": site["lobe_depth"],
        "axis": tuple(round(float(v), 6) for v in rotation @ np.asarray(site["axis"], dtype=float)),
        # scene/meshes.frame_from_axis starts a fruit's lobes from world x: under a half turn about z that start
        # turns by half a turn about the fruit's axis too, so the copy's twist adds it and the copy's mesh is its
        # site's turned (a view may draw one as the other)
        "twist": round((float(site["twist"]) + (math.pi if math.cos(yaw) < 0 else 0.0)) % (2 * math.pi), 6),
        "peduncle": {"points": [moved(point) for point in site["peduncle"]["points"]], "radius": site["peduncle"]["radius"]},
        "calyx": None if calyx is None else {"sepals": calyx["sepals"], "reach": round(float(calyx["reach"]) * scale, 6)},
    }


class Workstation(Frozen):
    center: Vec3
    size: Size3


class Prototype(Frozen):
    """A plant grown once (its pot's base at x = y = 0) and stood in many places. Of the neighbouring rows: its fruit
    are drawn but never counted (the masks mark them NEIGHBOUR_FRUIT_ID, and they are not in the scene's `peppers`).
    Of the scanned rows (the scene's `prototypes`): its fruit are the sites where a copy's own fruit may hang, each
    copy drawing which sites carry fruit and each fruit's colour, ripeness and size."""

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
    shared: int | None = WhenSet("The prototypes are the first `shared` of the scene's own `prototypes` (scene.json "
                                 "then lists them there only).", ge=1)

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
    prototypes: list[Prototype] | None = WhenSet("The plants that the scanned plants are copies of, each grown once "
                                                 "(plants.prototypes); none: every plant grown in its place.")
    environment: Environment | None = WhenSet("The film greenhouse round the room; none: plain walls.")

    @model_validator(mode="before")
    @classmethod
    def _whole_copy_fruit(cls, data: Any) -> Any:
        """A copy's fruit as scene.json keeps it (its COPY_FRUIT fields) made whole from its plant's prototype."""
        if not isinstance(data, dict):
            return data
        environment = data.get("environment")
        if isinstance(environment, dict) and "prototypes" not in environment and isinstance(environment.get("shared"), int):
            if not isinstance(data.get("prototypes"), list) or not 1 <= environment["shared"] <= len(data["prototypes"]):
                raise ValueError(f"environment.shared: {environment['shared']} but the scene has "
                                 f"{len(data.get('prototypes') or ())} prototypes")
            data = {**data, "environment": {**environment, "prototypes": data["prototypes"][:environment["shared"]]}}
        if not isinstance(data.get("peppers"), list):
            return data
        if not any(isinstance(p, dict) and "site" in p and "center" not in p for p in data["peppers"]):
            return data
        plants, prototypes = data.get("plants"), data.get("prototypes")
        peppers = []
        for index, pepper in enumerate(data["peppers"]):
            if isinstance(pepper, dict) and "site" in pepper and "center" not in pepper:
                try:
                    extra = set(pepper) - set(COPY_FRUIT)
                    if extra:
                        raise ValueError(f"{sorted(extra)[0]} is not kept for a copy's fruit")
                    if not isinstance(pepper["plant"], int) or pepper["plant"] < 0:
                        raise ValueError(f"plant {pepper['plant']!r} is not a plant's id")
                    plant = plants[pepper["plant"]]
                    if plant.get("prototype") is None:
                        raise ValueError(f"plant {pepper['plant']} is no copy of a prototype")
                    if not isinstance(plant["prototype"], int) or not 0 <= plant["prototype"] < len(prototypes or ()):
                        raise ValueError(f"its plant's prototype, plants.{pepper['plant']}.prototype: "
                                         f"{plant['prototype']!r} but there are {len(prototypes or ())} prototypes")
                    prototype = prototypes[plant["prototype"]]
                    if not isinstance(pepper["site"], int) or not 0 <= pepper["site"] < len(prototype["fruit"]):
                        raise ValueError(f"site {pepper['site']} but its prototype has {len(prototype['fruit'])}")
                    pepper = copy_fruit(pepper, plant["position"], float(plant["yaw"]), prototype["plant"]["position"],
                                        prototype["fruit"][pepper["site"]])
                except (KeyError, IndexError, TypeError, AttributeError, ValueError) as exc:
                    detail = exc if isinstance(exc, ValueError) else f"no {exc}" if isinstance(exc, KeyError) else "malformed"
                    raise ValueError(f"peppers.{index}: a copy's fruit that does not resolve ({detail})") from None
            peppers.append(pepper)
        return {**data, "peppers": peppers}

    @model_serializer(mode="wrap")
    def _dump(self, handler: Any) -> dict[str, Any]:
        data = handler(self)
        if self.environment is not None and self.environment.shared:  # the neighbouring rows' are the scene's prototypes
            data["environment"].pop("prototypes")
        if self.prototypes:  # a copy's fruit: its own draws only, the rest is its site's
            data["peppers"] = [{key: p[key] for key in COPY_FRUIT if key in p} if p.get("site") is not None else p
                               for p in data["peppers"]]
        return data

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
            if plant.prototype is not None and plant.prototype >= len(self.prototypes or ()):
                raise ValueError(f"plants.{index}.prototype: {plant.prototype} but there are "
                                 f"{len(self.prototypes or ())} prototypes")
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
        if self.environment is not None and self.environment.shared:
            if self.environment.prototypes != (self.prototypes or [])[:self.environment.shared]:
                raise ValueError(f"environment.shared: {self.environment.shared}, but the neighbouring rows' prototypes "
                                 "are not the first of the scene's")
        prototypes = self.environment.prototypes if self.environment and not self.environment.shared else []
        for where, plant in [*((f"plants.{p.id}", p) for p in self.plants),
                             *((f"prototypes.{i}.plant", p.plant) for i, p in enumerate(self.prototypes or ())),
                             *((f"environment.prototypes.{i}.plant", p.plant) for i, p in enumerate(prototypes))]:
            for index, leaf in enumerate(plant.leaves):
                if leaf.template is not None and leaf.template >= len(LEAF_SHAPES):
                    raise ValueError(f"{where}.leaves.{index}.template: {leaf.template} but there are "
                                     f"{len(LEAF_SHAPES)} leaf templates")
        return self

    def plant(self, plant_id: int) -> Plant:
        plants = self.plants
        if 0 <= plant_id < len(plants) and plants[plant_id].id == plant_id:
            return plants[plant_id]
        # a scene cut to some rows (`of_rows`) keeps its plants' ids, which are then no places in its list
        key, by_id = self.__dict__.get("_by_id", (None, None))
        if key != id(plants):
            by_id = {plant.id: plant for plant in plants}
            self.__dict__["_by_id"] = (id(plants), by_id)
        return by_id[plant_id]

    def of_rows(self, row_ids: Iterable[int]) -> Scene:
        """The scene as a scan of some of its rows is counted against: those rows (in the scene's order), their plants
        and the plants' fruit; the room, workstation, prototypes and environment as they are. The plants keep their ids,
        so look one up with `plant(id)`, not by its place in `plants`. Every row asked for: the scene itself. A row the
        scene lacks is refused in one line."""
        wanted, known = {int(row_id) for row_id in row_ids}, [row.id for row in self.rows]
        missing = sorted(wanted - set(known))
        if missing:
            raise UserError(f"the scene has no row {missing[0]} (its rows: {', '.join(map(str, known)) or 'none'})")
        if wanted == set(known):
            return self
        plants = [plant for plant in self.plants if plant.row in wanted]
        ids = {plant.id for plant in plants}
        cut = self.model_copy(update={"rows": [row for row in self.rows if row.id in wanted], "plants": plants,
                                      "peppers": [pepper for pepper in self.peppers if pepper.plant in ids]})
        for index in ("_by_plant", "_by_id"):  # built for the whole scene's lists
            cut.__dict__.pop(index, None)
        return cut

    def peppers_of(self, plant_id: int) -> list[Pepper]:
        # An index built on first use (a scene of a thousand plants is asked for each), kept beside the fields of
        # the frozen model and tied to its list of peppers, so a copy with other peppers builds its own.
        key, by_plant = self.__dict__.get("_by_plant", (None, None))
        if key != id(self.peppers):
            by_plant = {}
            for pepper in self.peppers:
                by_plant.setdefault(pepper.plant, []).append(pepper)
            self.__dict__["_by_plant"] = (id(self.peppers), by_plant)
        return list(by_plant.get(plant_id, ()))

    def prototype_of(self, plant: Plant) -> Prototype | None:
        """The prototype a copy stands for (None for a plant grown in its place)."""
        return None if plant.prototype is None else self.prototypes[plant.prototype]

    def body(self, plant: Plant) -> Plant:
        """The plant whose stem, branches, leaves, flowers and strings `plant` has: itself, or its prototype (in the
        prototype's frame: `placement` maps it into the world)."""
        prototype = self.prototype_of(plant)
        return plant if prototype is None else prototype.plant

    def strings_of(self, plant: Plant) -> list[tuple[float, float, float]] | None:
        """Where a plant's strings are tied, in the world (a copy's are its prototype's, moved with it)."""
        prototype = self.prototype_of(plant)
        if prototype is None:
            return plant.strings
        if not prototype.plant.strings:
            return None
        transform = placement(plant, prototype.plant)
        return [tuple(round(float(v), 6) for v in transform[:3, :3] @ foot + transform[:3, 3]) for foot in prototype.plant.strings]


def placement(plant: Plant, prototype: Plant) -> np.ndarray:
    """4x4 map from a prototype's frame to its copy `plant`'s: a turn by the copy's yaw about the prototype's axis,
    which lands on the copy's position."""
    return _placement(plant.position, plant.yaw or 0.0, prototype.position)


def _placement(position: Any, yaw: float, origin: Any) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    transform = np.eye(4)
    transform[:2, :2] = [[c, -s], [s, c]]
    transform[:3, 3] = np.asarray(position, dtype=float) - transform[:3, :3] @ np.asarray(origin, dtype=float)
    return transform


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
