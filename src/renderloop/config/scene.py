"""The greenhouse, its plants and their fruit (`greenhouse`, `plants`)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from renderloop.config.fields import (
    MAX_FLOOR_AREA,
    MAX_LEAVES,
    MAX_LEAVES_PER_PLANT,
    MAX_PLANTS,
    MAX_PLANTS_PER_TABLE,
    MAX_ROOM_SIDE,
    MAX_TABLES,
    Count,
    Fraction,
    Position2,
    Real,
    Strict,
    inside_room,
    ordered_range,
)

# Each prototype is a whole plant grown (0.4 s and 500 leaves for a high-wire one): 500 are minutes of growth.
MAX_PROTOTYPES = 500
RIPE_COLORS = frozenset({"red", "yellow", "orange"})  # the rest (green) is unripe: scene.json says which each fruit is


# A table: width (x), length (y), height, m. scene/world.py builds it as a 4 cm slab on 4 cm legs, so at least 0.1 m.
BoxSize = tuple[Real(0.1, 20.0), Real(0.1, MAX_ROOM_SIDE), Real(0.1, 5.0)]


class EnvironmentConfig(Strict):
    """What surrounds the scanned rows (scene/environment.py). Each scene draws its own value from every range
    below (equal ends: a fixed value), stored in scene.json, so one seed gives one greenhouse and one light."""

    kind: Literal["plain", "film"] = Field(
        "plain", description="'plain': grey walls round the room and a flat-colour sky (the look the shipped detector "
        "was trained on; the ranges below are not used). 'film': the room is one compartment of a film-clad greenhouse "
        "that goes on beyond it (`extent`): white film walls and a Venlo roof on gutters, posts and trusses, a crop "
        "wire over every row with a string down to each plant, neighbouring rows of plants (not scanned, not counted, "
        "never in the masks) on white ground cover, lit in Cycles by a sky model and the sun at the drawn time of day "
        "through the film. Only the strings and wires inside the room are collision objects.")
    hour: tuple[Real(0.0, 24.0), Real(0.0, 24.0)] = Field(
        (8.0, 17.0), description="Local solar time range, h (12: noon); a draw when the sun stands lower than 0.09 rad "
        "is moved to the nearest time it stands that high.")
    day_of_year: tuple[Count(1, 366), Count(1, 366)] = Field(
        (60, 300), description="Day of the year range (1: 1 January), which sets the sun's path; a sweet-pepper crop is "
        "harvested from March to November.")
    latitude: Real(-1.2, 1.2) = Field(0.91, description="Latitude of the greenhouse, rad, north positive (0.91: the "
                                      "Dutch glasshouse district). Rows run north-south, along the world's y.")
    cloud: tuple[Fraction, Fraction] = Field(
        (0.0, 1.0), description="Cloud cover range, 0-1: 0 a clear sky with the sun, 1 overcast, every light diffuse.")
    aerosol: tuple[Real(0.0, 10.0), Real(0.0, 10.0)] = Field(
        (0.5, 3.0), description="Aerosol density range of the sky model (Blender's Multiple Scattering sky): dust, haze "
        "and water droplets, 1 a clear day, 3 or more hazy; it warms and dims the sun and brightens the sky.")
    film_age: tuple[Fraction, Fraction] = Field(
        (0.0, 1.0), description="Age of the roof and wall film range, 0-1: 0 new and clear, 1 yellowed, dusty and "
        "more diffusing, letting less light through (the 'film' entry of scene/materials.py).")
    clutter: tuple[Fraction, Fraction] = Field(
        (0.3, 1.0), description="Clutter range, 0-1: how many yellow sticky insect traps hang over the neighbouring "
        "rows, 1 being as many as scene/environment.py's TRAPS_PER_METRE says.")
    extent: Real(0.0, 50.0) = Field(
        4.5, description="How far the greenhouse goes on beyond the room on every side, m: the neighbouring rows stand "
        "there and its film walls at the end. Nothing beyond the camera's far clip is drawn (camera.clip).")
    row_pitch: Real(0.5, 10.0) = Field(1.6, description="Distance between the neighbouring rows beyond the room, m.")
    gutter_height: Real(1.0, 20.0) = Field(
        4.5, description="Height of the gutters that carry the film roof, m; the trusses under them must stay above the "
        "room (the flight volume).")
    wire_height: Real(0.5, 20.0) = Field(
        3.8, description="Height of the crop wire above every row that the plants' strings hang from, m; above the "
        "plants' tops and below the gutters.")

    @model_validator(mode="after")
    def _ranges(self) -> EnvironmentConfig:
        for name in ("hour", "day_of_year", "cloud", "aerosol", "film_age", "clutter"):
            ordered_range(getattr(self, name), name)
        if self.wire_height >= self.gutter_height:
            raise ValueError(f"wire_height: {self.wire_height} m is not below the gutters at {self.gutter_height} m")
        return self


class GreenhouseConfig(Strict):
    """Room, tables (one row of plants each) and the manipulator workstation."""

    size: tuple[Real(1.0, MAX_ROOM_SIDE), Real(1.0, MAX_ROOM_SIDE), Real(1.0, 50.0)] = Field(
        (12.0, 10.0, 3.5), description=f"Room length (x), width (y) and height (z), m; the floor at most {MAX_FLOOR_AREA:g} m².")
    tables: list[Position2] = Field(
        default=[(x, y) for y in (-2.5, 2.5) for x in (-3.0, -1.0, 1.0, 3.0)],
        min_length=1,
        max_length=MAX_TABLES,
        description="Table centres (x, y), m, the room's centre at the origin; each table is one row of plants along y.",
    )
    table_size: BoxSize = Field((0.5, 2.0, 0.6), description="Table width (x), length (y) and height (z), m.")
    plants_per_table: Count(1, MAX_PLANTS_PER_TABLE) = Field(
        4, description=f"Plants in the row on each table; all tables together hold at most {MAX_PLANTS}.")
    plant_spacing: Real(0.05, 10.0) = Field(0.5, description="Distance between neighbouring plants along a table, m.")
    workstation_center: Position2 = Field((0.0, 0.0), description="Centre (x, y) of the manipulator workstation, m.")
    workstation_size: BoxSize = Field((0.5, 1.0, 0.6), description="Workstation table width (x), length (y) and height (z), m.")
    environment: EnvironmentConfig = Field(
        EnvironmentConfig(), description="What surrounds the scanned rows: plain walls, or a film greenhouse with its "
        "light and neighbouring rows.")

    @model_validator(mode="after")
    def _tables_fit(self) -> GreenhouseConfig:
        if self.size[0] * self.size[1] > MAX_FLOOR_AREA:
            raise ValueError(f"size: a {self.size[0]:g} x {self.size[1]:g} m floor is larger than {MAX_FLOOR_AREA:g} m²")
        total = len(self.tables) * self.plants_per_table
        if total > MAX_PLANTS:
            raise ValueError(f"plants_per_table: {len(self.tables)} tables of {self.plants_per_table} plants are more than {MAX_PLANTS} plants")
        length = self.table_size[1]
        if (self.plants_per_table - 1) * self.plant_spacing > length + 1e-9:
            raise ValueError(
                f"plants_per_table: {self.plants_per_table} plants {self.plant_spacing} m apart "
                f"do not fit on a {length} m table"
            )
        for x, y in self.tables:
            if not inside_room((x, y), self.table_size, self.size):
                raise ValueError(f"tables: table at ({x}, {y}) lies outside the {self.size[0]} x {self.size[1]} m room")
        if not inside_room(self.workstation_center, self.workstation_size, self.size):
            raise ValueError(f"workstation_center: the workstation at {tuple(self.workstation_center)} lies outside the "
                             f"{self.size[0]} x {self.size[1]} m room")
        return self


class PotConfig(Strict):
    radius_top: Real(0.01, 1.0) = Field(0.1, description="Pot radius at the rim, m.")
    radius_bottom: Real(0.01, 1.0) = Field(0.075, description="Pot radius at the base, m.")
    height: Real(0.01, 2.0) = Field(0.18, description="Pot height; the canopy starts at its rim, m.")


class PepperConfig(Strict):
    """Sweet peppers: blocky lobed fruit about 7-10 cm long."""

    # Up to 100: a 3 m canopy holds that many small fruit; whether they fit is the scene stage's check (a UserError).
    per_side: tuple[Count(1, 100), Count(1, 100)] = Field(
        (1, 5), description="Fewest and most fruit on each side (facing -x, +x) of a bearing plant.")
    length: tuple[Real(0.01, 0.5), Real(0.01, 0.5)] = Field((0.07, 0.10), description="Fruit length range, m.")
    width_ratio: tuple[Real(0.1, 3.0), Real(0.1, 3.0)] = Field((0.8, 1.0), description="Fruit width over its length, range.")
    lobes: tuple[Literal[3, 4], Literal[3, 4]] = Field((3, 4), description="Range of the number of lobes, 3 or 4.")
    # scene/meshes.pepper refuses lobe_depth >= 0.5 (a ValueError in the scene stage otherwise).
    lobe_depth: tuple[Real(0.0, 0.5, high_open=True), Real(0.0, 0.5, high_open=True)] = Field(
        (0.05, 0.14), description="Range of the lobes' depth as a fraction of the fruit's radius.")
    max_tilt: Real(0.0, math.pi / 2) = Field(0.35, description="Hanging axis tilt from vertical, rad.")
    colors: dict[Literal["red", "yellow", "orange", "green"], Real(0.0, 1e6)] = Field(
        default={"red": 1.0}, description="Relative weight of each colour class; green is unripe."
    )

    @model_validator(mode="after")
    def _ranges(self) -> PepperConfig:
        for name in ("per_side", "length", "width_ratio", "lobes", "lobe_depth"):
            ordered_range(getattr(self, name), name)
        if not self.colors or sum(self.colors.values()) <= 0:
            raise ValueError("colors: at least one colour needs a positive weight")
        return self


class PepperStyleConfig(Strict):
    """The foliage of the 'pepper' plant style: many instanced leaves on a dichotomously branching plant."""

    leaves: tuple[Count(1, MAX_LEAVES_PER_PLANT), Count(1, MAX_LEAVES_PER_PLANT)] = Field(
        (110, 180), description="Fewest and most leaves of a plant (a greenhouse pepper carries 60-200).")
    leaf_length: tuple[Real(0.005, 1.0), Real(0.005, 1.0)] = Field(
        (0.07, 0.17), description="Leaf blade length range, m (the petiole adds a quarter of it).")
    leaf_width_ratio: tuple[Real(0.05, 2.0), Real(0.05, 2.0)] = Field(
        (0.45, 0.6), description="Leaf blade width over its length, range.")
    leaf_tint: tuple[Fraction, Fraction] = Field(
        (0.0, 0.0), description="Range of how far a plant's healthy leaves go from dark green to a light yellow-green, "
        "0-1, drawn per plant (cultivar, nutrition, light); `renderloop dataset` draws from 0-1.")
    yellowed: Fraction = Field(0.05, description="Share of leaves yellowed with age, 0-1.")
    damaged: Fraction = Field(0.06, description="Share of leaves with a torn edge or an eaten hole, 0-1.")
    dusty: Fraction = Field(0.1, description="Share of leaves under a grey film of dust or spray residue, 0-1.")
    fruit_window: Fraction = Field(
        0.6, description="Radius of the leaf-free window in front of each fruit as the scan sees it (from its side of "
        "the row), over the fruit's bounding radius, 0-1: leaves may hide a fruit's rim, never its middle.")

    @model_validator(mode="after")
    def _ranges(self) -> PepperStyleConfig:
        for name in ("leaves", "leaf_length", "leaf_width_ratio", "leaf_tint"):
            ordered_range(getattr(self, name), name)
        return self


class HighWireConfig(Strict):
    """The stems of the 'highwire' plant style: a commercial crop trained up strings to a crop wire."""

    stems: tuple[Count(1, 8), Count(1, 8)] = Field(
        (2, 4), description="Fewest and most stems of a plant, each trained up its own string (growers keep 2-4).")
    internode: tuple[Real(0.02, 0.5), Real(0.02, 0.5)] = Field(
        (0.06, 0.11), description="Length range of a stem's internodes, m: a node, its leaf and side shoot each step.")
    side_shoots: Fraction = Field(
        0.7, description="Share of a stem's nodes that keep a side shoot, 0-1 (pruned after its first leaf or fruit).")
    leafless: Fraction = Field(
        0.15, description="Share of the canopy's height, from the bottom, whose old leaves the grower has stripped, 0-1.")
    wind: Real(0.0, 0.05) = Field(
        0.008, description="How far a stem winds round its string, m (the string stays in the stem's reach).")

    @model_validator(mode="after")
    def _ranges(self) -> HighWireConfig:
        for name in ("stems", "internode"):
            ordered_range(getattr(self, name), name)
        return self


_TEMPLATE_LEAF_STYLES = ("pepper", "highwire")


class PlantConfig(Strict):
    """Procedural pepper plants: stem, branches, leaves, flowers, fruit, pot."""

    style: Literal["simple", "pepper", "highwire"] = Field(
        "simple", description="How plants grow. 'simple': 30-55 smooth leaves on a few straight branches (`branches`, "
        "`leaves` and `leaf_*` describe it). 'pepper': a dichotomously branching pot-grown plant, fruit hanging from "
        "its nodes on a peduncle with a calyx, dense instanced leaves with veins, wrinkles and a waxy sheen "
        "(`pepper_style` describes them). 'highwire': a commercial crop's plant, 2-4 stems each winding up its string "
        "from node to node with pruned side shoots, the same fruit, leaves and flowers (`highwire` and `pepper_style` "
        "describe it). One seed places the same fruit (where, how big, which colour) in the 'simple' and 'pepper' "
        "styles.")
    pepper_style: PepperStyleConfig = Field(PepperStyleConfig(), description="The foliage of the 'pepper' and "
                                            "'highwire' styles.")
    highwire: HighWireConfig = Field(HighWireConfig(), description="The stems of the 'highwire' style.")
    bearing: Count(1, MAX_PLANTS) | None = Field(20, description="Plants bearing fruit; null means every plant.")
    # 32: the reference work's greenhouse (and the config's default) grows every plant in its place, as before.
    prototypes: Count(1, MAX_PROTOTYPES) = Field(
        32, description="Size of the library of plants grown for the scanned rows, plants. A greenhouse of more plants "
        "than this grows only these (from the run's seed) and stands each of its plants as a copy of one, turned or not "
        "by half a turn, with fruit of its own drawn from the seed on the prototype's fruit sites (which sites carry "
        "fruit, each fruit's colour, ripeness and size), so its build time and scene.json grow by bytes a plant; with "
        "as many plants or fewer, every plant grows in its place.")
    # Greenhouse peppers are trained up to 3-4 m.
    volume: tuple[Real(0.05, 3.0), Real(0.05, 3.0), Real(0.05, 5.0)] = Field(
        (0.44, 0.44, 0.5), description="Canopy box above the pot (x, y, z), m.")
    stem_radius: Real(0.001, 0.1) = Field(0.006, description="Main stem radius, m; branches are 0.6 of it.")
    branches: tuple[Count(1, 100), Count(1, 100)] = Field((2, 4), description="Fewest and most branches of a plant.")
    leaves: tuple[Count(1, MAX_LEAVES_PER_PLANT), Count(1, MAX_LEAVES_PER_PLANT)] = Field(
        (30, 55), description=f"Fewest and most leaves of a plant; the greenhouse's plants together at most {MAX_LEAVES}.")
    leaf_length: tuple[Real(0.005, 1.0), Real(0.005, 1.0)] = Field((0.07, 0.14), description="Leaf blade length range, m.")
    leaf_width_ratio: tuple[Real(0.05, 2.0), Real(0.05, 2.0)] = Field(
        (0.4, 0.6), description="Leaf blade width over its length, range.")
    leaf_curvature: tuple[Real(0.0, 100.0), Real(0.0, 100.0)] = Field(
        (0.0, 12.0), description="Range of the midrib's bend, 1/m (12: a 14 cm leaf bends through about 1 rad).")
    flowers: tuple[Count(0, 200), Count(0, 200)] = Field((1, 5), description="Fewest and most flowers of a plant.")
    pot: PotConfig = Field(PotConfig(), description="The plant's pot.")
    peppers: PepperConfig = Field(PepperConfig(), description="The fruit of bearing plants.")

    @model_validator(mode="after")
    def _ranges(self) -> PlantConfig:
        for name in ("branches", "leaves", "leaf_length", "leaf_width_ratio", "leaf_curvature", "flowers"):
            ordered_range(getattr(self, name), name)
        return self

    @property
    def most_leaves(self) -> int:
        """The most leaves one plant of this style can have."""
        return self.pepper_style.leaves[1] if self.style in _TEMPLATE_LEAF_STYLES else self.leaves[1]

    @property
    def leaves_field(self) -> str:
        """The config field that bounds this style's leaves."""
        return "plants.pepper_style.leaves" if self.style in _TEMPLATE_LEAF_STYLES else "plants.leaves"
