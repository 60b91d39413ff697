"""Typed configuration of a run: one pydantic model per subsystem, presets, YAML in and out.

The defaults are the numbers of the reference work (docs/design.md), so the `paper`
preset is almost empty; `demo` shrinks the greenhouse to one table. A user YAML
file is deep-merged over the preset, and every unknown key is an error, because a
misspelt field that silently keeps its default is the worst kind of config bug.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from renderloop.errors import UserError, problem
from renderloop.perception.tiling import LAYOUT_PATTERN, Layout, layout


def Real(low: float, high: float, *, low_open: bool = False, high_open: bool = False) -> Any:
    """A finite float in [low, high]; `low_open`/`high_open` leave an end out (gt/lt instead of ge/le)."""
    lower = {"gt": low} if low_open else {"ge": low}
    upper = {"lt": high} if high_open else {"le": high}
    return Annotated[float, Field(**lower, **upper, allow_inf_nan=False)]


def Count(low: int, high: int) -> Any:
    """An integer in [low, high]."""
    return Annotated[int, Field(ge=low, le=high)]


# Building blocks of the fields below. Every field is bounded above and below: the bounds let every real
# greenhouse and robot through and stop a typo (a missing decimal point, a unit off by 1000) before it
# costs a long run or crashes a stage later.
Fraction = Real(0.0, 1.0)
Angle = Real(-math.pi, math.pi)  # rad
Coordinate = Real(-100.0, 100.0)  # m: half the largest room side
Position2 = tuple[Coordinate, Coordinate]
Gain = Real(0.0, 1e5)

MAX_ROOM_SIDE = 200.0  # m
# The planner routes on a 5 cm occupancy grid of the whole floor: one hectare is 4 M cells, about 2 GB and
# seconds a transit; a larger floor would exhaust memory before it flew.
MAX_FLOOR_AREA = 10_000.0  # m²
MAX_TABLES = 500
MAX_PLANTS_PER_TABLE = 200
# Growing a plant takes about 60 ms (paper scene: 32 plants in 1.8 s): 5000 plants are minutes of scene
# generation, and as many ellipses for the planner, the simulation and the renderer.
MAX_PLANTS = 5000
MAX_LEAVES_PER_PLANT = 2000
# Every leaf is a mesh in scene.json and in Blender: 200 000 leaves are about 40 MB of scene and 9 M vertices.
MAX_LEAVES = 200_000
MAX_PIXELS = 8192 * 4096  # 33.5 Mpx, an 8K frame: its float RGB, depth and mask buffers alone are about 0.6 GB
MAX_CAMERA_RATE_HZ = 100.0

PEPPER_COLORS = ("red", "yellow", "orange", "green")
RIPE_COLORS = frozenset({"red", "yellow", "orange"})


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _ordered_range(value: tuple[float, float], name: str) -> None:
    if value[0] > value[1]:
        raise ValueError(f"{name}: minimum {value[0]} is larger than maximum {value[1]}")


def _inside_room(center: tuple[float, float], size: tuple[float, ...], room: tuple[float, ...]) -> bool:
    return abs(center[0]) + size[0] / 2 <= room[0] / 2 + 1e-9 and abs(center[1]) + size[1] / 2 <= room[1] / 2 + 1e-9


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
            _ordered_range(getattr(self, name), name)
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
            if not _inside_room((x, y), self.table_size, self.size):
                raise ValueError(f"tables: table at ({x}, {y}) lies outside the {self.size[0]} x {self.size[1]} m room")
        if not _inside_room(self.workstation_center, self.workstation_size, self.size):
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
            _ordered_range(getattr(self, name), name)
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
    yellowed: Fraction = Field(0.05, description="Share of leaves yellowed with age, 0-1.")
    damaged: Fraction = Field(0.06, description="Share of leaves with a torn edge or an eaten hole, 0-1.")
    dusty: Fraction = Field(0.1, description="Share of leaves under a grey film of dust or spray residue, 0-1.")
    fruit_window: Fraction = Field(
        0.6, description="Radius of the leaf-free window in front of each fruit as the scan sees it (from its side of "
        "the row), over the fruit's bounding radius, 0-1: leaves may hide a fruit's rim, never its middle.")

    @model_validator(mode="after")
    def _ranges(self) -> PepperStyleConfig:
        for name in ("leaves", "leaf_length", "leaf_width_ratio"):
            _ordered_range(getattr(self, name), name)
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
            _ordered_range(getattr(self, name), name)
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
            _ordered_range(getattr(self, name), name)
        return self

    @property
    def most_leaves(self) -> int:
        """The most leaves one plant of this style can have."""
        return self.pepper_style.leaves[1] if self.style in _TEMPLATE_LEAF_STYLES else self.leaves[1]

    @property
    def leaves_field(self) -> str:
        """The config field that bounds this style's leaves."""
        return "plants.pepper_style.leaves" if self.style in _TEMPLATE_LEAF_STYLES else "plants.leaves"


class RotorConfig(Strict):
    """Rotor thrust F = kf w^2, drag moment M = km F (docs/design.md)."""

    kf: Real(1e-9, 1e-2) = Field(8.54858e-6, description="Thrust coefficient kf of F = kf w², N s²/rad².")
    km: Real(0.0, 1.0, low_open=True) = Field(0.016, description="Drag moment over thrust km of M = km F, m.")
    max_speed: Real(10.0, 20_000.0) = Field(1475.0, description="Largest rotor speed, rad/s.")
    time_constant: Real(0.0, 1.0) = Field(0.0, description="First-order motor lag, s; 0 means none.")
    layout: Literal["x", "+"] = Field("x", description="Quadrotor layout: 'x' (rotors between the axes) or '+' (on them).")


class ArmConfig(Strict):
    """3-DoF pitch chain below the body with the RGB-D camera on its tip."""

    mount: tuple[Real(-1.0, 1.0), Real(-1.0, 1.0), Real(-1.0, 1.0)] = Field(
        (0.0, 0.0, -0.08), description="Joint 1 position in the body frame, m.")
    link_lengths: tuple[Real(0.01, 2.0), Real(0.01, 2.0), Real(0.01, 2.0)] = Field(
        (0.12, 0.14, 0.3), description="Length of links 1, 2 and 3 (the last carries the camera), m.")
    link_masses: tuple[Real(0.001, 10.0), Real(0.001, 10.0), Real(0.001, 10.0)] = Field(
        (0.05, 0.05, 0.12), description="Mass of links 1, 2 and 3, kg.")
    joint_limits: tuple[Angle, Angle] = Field((-1.6, 1.6), description="Lower and upper limit of every joint, rad.")
    nominal_posture: tuple[Angle, Angle] = Field((0.0, 0.0), description="q1, q2 that inverse kinematics keeps, rad; q3 sets the pitch.")
    max_torque: Real(0.01, 1000.0) = Field(2.0, description="Joint motor torque limit, N m.")

    @model_validator(mode="after")
    def _limits(self) -> ArmConfig:
        _ordered_range(self.joint_limits, "joint_limits")
        return self


class RobotConfig(Strict):
    mass: Real(0.05, 100.0) = Field(2.083, description="UAV body mass without the arm, kg.")
    inertia: tuple[Real(1e-6, 100.0), Real(1e-6, 100.0), Real(1e-6, 100.0)] = Field(
        (0.0827, 0.0827, 0.0104), description="Body principal moments of inertia (x, y, z), kg m².")
    arm_length: Real(0.02, 5.0) = Field(0.314, description="Body centre to rotor axis, m.")
    prop_radius: Real(0.01, 2.0) = Field(0.12, description="Propeller radius, m.")
    leg_length: Real(0.01, 2.0) = Field(0.2, description="Landing legs below the body centre, m.")
    rotor: RotorConfig = Field(RotorConfig(), description="The four rotors.")
    arm: ArmConfig = Field(ArmConfig(), description="The camera arm.")
    home: tuple[Coordinate, Coordinate, Real(0.0, 50.0)] = Field((0.0, -1.2, 0.0), description="Take-off point on the floor, m.")

    @model_validator(mode="after")
    def _physical_inertia(self) -> RobotConfig:
        # No rigid body has a principal moment larger than the other two together; MuJoCo refuses one.
        a, b, c = self.inertia
        if a > b + c or b > a + c or c > a + b:
            raise ValueError(f"inertia: no rigid body has principal moments {list(self.inertia)}: "
                             "each must be at most the sum of the other two")
        return self


def Range(low: float, high: float) -> Any:
    """A [lowest, highest] pair within [low, high]: each frame draws its value from it (equal ends: a fixed value)."""
    return tuple[Real(low, high), Real(low, high)]


class SensorConfig(Strict):
    """The colour stream of a RealSense D435-class camera (render/sensor.py); each frame draws every value from its
    range. Off: the ideal stream only. On: `rgb_sensor/` beside `rgb/`, and perception reads the sensor's frames."""

    enabled: bool = Field(False, description="Render the sensor stream rgb_sensor/ beside the ideal rgb/.")
    exposure_time: Range(0.0, 0.2) = Field(
        (0.008, 0.025), description="Shutter time, s (a D435's indoor auto exposure): Cycles blurs rgb_sensor/ with the "
        "camera's flown motion over it (render/motion.py); raster frames are not blurred; 0: no blur.")
    exposure_target: Range(0.01, 1.0) = Field(
        (0.12, 0.22), description="Centre-weighted mean linear luminance auto exposure aims for (0.18: mid grey).")
    gain: Range(0.01, 100.0) = Field((0.5, 16.0), description="Smallest and largest gain auto exposure may set.")
    white_balance_error: Range(0.0, 0.5) = Field((0.0, 0.04), description="Sigma of each channel's white-balance gain error.")
    vignetting: Range(0.0, 1.0) = Field((0.05, 0.3), description="Share of light lost in the image corners.")
    focus_distance: Range(0.05, 100.0) = Field((0.6, 1.2), description="Distance the fixed-focus lens is sharp at, m.")
    defocus: Range(0.0, 20.0) = Field((0.0, 1.5), description="Blur radius per 1/m away from focus, px m.")
    shot_noise: Range(0.0, 0.1) = Field((0.0005, 0.003), description="Shot-noise variance per unit of linear signal and gain.")
    read_noise: Range(0.0, 0.1) = Field((0.001, 0.004), description="Read-noise sigma in linear units before the gain.")
    sharpen: Range(0.0, 3.0) = Field((0.2, 0.8), description="ISP unsharp-mask amount (1 = 100 %).")
    jpeg_quality: Range(10.0, 100.0) = Field((80.0, 100.0), description="JPEG quality of the stream; 100: not compressed.")


class CameraConfig(Strict):
    width: Count(16, 8192) = Field(640, description=f"Image width, px; width x height at most {MAX_PIXELS} px.")
    height: Count(16, 8192) = Field(480, description="Image height, px.")
    hfov_deg: Real(1.0, 179.0, low_open=True, high_open=True) = Field(57.0, description="Horizontal field of view, deg.")
    clip: tuple[Real(0.01, 100.0), Real(0.01, 100.0)] = Field(
        (0.2, 5.0), description="Near and far clipping distance (the depth range), m.")
    rate_hz: Real(0.001, MAX_CAMERA_RATE_HZ) = Field(
        5.0, description="Camera frame rate along the trajectory, Hz; at most controller.rate_hz.")
    sensor: SensorConfig = Field(SensorConfig(), description="The real camera's colour stream.")

    @model_validator(mode="after")
    def _clip(self) -> CameraConfig:
        if self.clip[0] >= self.clip[1]:
            raise ValueError("clip: near must be smaller than far")
        if self.width * self.height > MAX_PIXELS:
            raise ValueError(f"width: a {self.width} x {self.height} px image is more than {MAX_PIXELS} px")
        return self

    @property
    def fx(self) -> float:
        return self.width / (2.0 * math.tan(math.radians(self.hfov_deg) / 2.0))


class PlannerConfig(Strict):
    """Elliptical scan waypoints and TOPP-RA limits for q* = (x, y, z, yaw, q1, q2, q3)."""

    distance: Real(0.1, 10.0) = Field(1.0, description="Horizontal distance from a plant's axis to the UAV body on its scan ellipse, m.")
    semi_axes: tuple[Real(0.01, 5.0), Real(0.01, 5.0)] = Field(
        (0.125, 0.25), description="Half width (along the row) and half height of the camera's scan ellipse, m.")
    points_per_ellipse: Count(1, 360) = Field(10, description="Scan waypoints on each ellipse.")
    bands: Count(1, 20) = Field(
        1, description="Ellipses stacked up the canopy on each side of a plant, each aimed at the middle of its own "
        "band of the canopy's height: 1 where the camera sees the whole canopy, more for a tall crop.")
    max_camera_pitch: Real(0.0, 1.5) = Field(0.6, description="Largest camera pitch, rad; 0.6 lets the camera aim at the centroid from the ellipse top.")
    # Lower limits keep a trajectory (its length over its speed, times sample_rate_hz samples) within memory.
    velocity_limits: tuple[Real(0.05, 20.0), ...] = Field(
        (1.5, 1.5, 0.5, 0.3, 1.0, 1.0, 1.0), min_length=7, max_length=7,
        description="Speed limit of x, y, z (m/s), yaw, q1, q2, q3 (rad/s).")
    acceleration_limits: tuple[Real(0.05, 50.0), ...] = Field(
        (0.6, 0.6, 0.4, 0.3, 1.2, 1.2, 1.2), min_length=7, max_length=7,
        description="Acceleration limit of x, y, z (m/s²), yaw, q1, q2, q3 (rad/s²).")
    limit_margin: Real(0.1, 1.0) = Field(0.98, description="Fraction of each limit given to TOPP-RA.")
    sample_rate_hz: Real(1.0, 1000.0) = Field(100.0, description="Rate at which the trajectory is sampled into trajectory.csv, Hz.")


class PID(Strict):
    p: Gain = Field(0.0, description="Proportional gain, in the units of its loop (ControllerConfig).")
    i: Gain = Field(0.0, description="Integral gain, 1/s times the proportional units.")
    d: Gain = Field(0.0, description="Derivative gain, s times the proportional units.")
    limit: Real(1e-3, 1e5) | None = Field(None, description="Clamp on the loop's output, in its units; null means none.")


class ControllerConfig(Strict):
    """Cascade PID gains in SI units, and the loop rates.

    Position loops give velocity (1/s), velocity loops acceleration (m/s² per m/s; the xy
    gains are in rad of tilt per m/s as in the reference work, times g), the attitude loop
    body rates (1/s) and the rate loop angular acceleration (1/s, times the inertia).
    The xy and attitude gains are the authors'; z, rate and joint gains are retuned for
    these units (their rate and z gains acted on rotor-speed units). Joint PIDs act on
    joint acceleration through the arm's mass matrix, with gravity compensation.
    """

    rate_hz: Real(50.0, 1000.0) = Field(100.0, description="Control loop rate, Hz; its period is a whole number of physics steps.")
    physics_dt: Real(1e-4, 0.002) = Field(0.002, description="MuJoCo physics time step, s.")
    position_xy: PID = Field(PID(p=2.0, limit=3.0), description="Horizontal position loop: m/s per m; limit in m/s.")
    velocity_xy: PID = Field(PID(p=0.5, i=0.1), description="Horizontal velocity loop: rad of tilt per m/s, times g.")
    max_tilt: Real(0.0, 1.57, low_open=True, high_open=True) = Field(0.6, description="Largest commanded roll or pitch, rad.")
    position_z: PID = Field(PID(p=4.0, limit=2.0), description="Vertical position loop: m/s per m; limit in m/s.")
    velocity_z: PID = Field(PID(p=8.0, i=3.0), description="Vertical velocity loop: m/s² per m/s.")
    attitude: PID = Field(PID(p=7.0), description="Roll and pitch loop: rad/s per rad.")
    rate: PID = Field(PID(p=25.0, i=3.0), description="Body rate loop: rad/s² per rad/s, times the inertia.")
    yaw: PID = Field(PID(p=5.0), description="Yaw loop: rad/s per rad.")
    yaw_rate: PID = Field(PID(p=12.0, i=1.0), description="Yaw rate loop: rad/s² per rad/s, times the inertia.")
    joints: PID = Field(PID(p=400.0, i=200.0, d=32.0), description="Arm joint loops: rad/s² per rad, through the mass matrix.")
    compensate_arm_pitch: bool = Field(True, description="Joint 1 cancels the body's pitch, so the camera holds its planned pitch.")
    position_noise_std: Real(0.0, 1.0) = Field(0.0, description="UWB-like noise on the position fed back, m.")

    @model_validator(mode="after")
    def _whole_physics_steps(self) -> ControllerConfig:
        period = 1.0 / self.rate_hz
        steps = round(period / self.physics_dt)
        if steps < 1 or abs(steps * self.physics_dt - period) > 1e-9:
            raise ValueError(f"rate_hz: the control period 1/{self.rate_hz:g} s must be a whole number of "
                             f"physics steps of {self.physics_dt:g} s")
        return self


class DepthNoiseConfig(Strict):
    enabled: bool = Field(True, description="Add depth noise and edge dropout to the rendered depth.")
    sigma_at_1m: Real(0.0, 0.5) = Field(0.002, description="Depth noise sigma at 1 m, m; grows with z^2.")
    edge_dropout: Fraction = Field(0.5, description="Probability that a depth pixel on an object's edge reads no depth.")


# Cycles caps every light-path bounce count at 1024.
Bounces = Count(0, 1024)


class BouncesConfig(Strict):
    """Cycles' light-path limits, for a user trading light transport against time. Samples, not
    bounces, are what a frame costs: 3/1/1/2/2 instead of these saved 6 % at 4 samples on the paper scene."""

    total: Bounces = Field(6, description="Most bounces of a light path.")
    diffuse: Bounces = Field(3, description="Most diffuse bounces.")
    glossy: Bounces = Field(3, description="Most glossy bounces.")
    transmission: Bounces = Field(4, description="Most transmission bounces.")
    transparent: Bounces = Field(4, description="Most transparent bounces.")


class RasterConfig(Strict):
    """MuJoCo's OpenGL look, for a user trading it against speed: on 2 cores through llvmpipe the sun's shadow map
    and the multisampling are most of a dense frame's cost (docs/stages/render.md)."""

    shadows: bool = Field(True, description="The sun casts shadows (a 2048 x 2048 shadow map).")
    antialias: Count(0, 16) = Field(4, description="Multisamples per pixel of the colour image; 0 turns antialiasing off.")


class RendererConfig(Strict):
    backend: Literal["cycles", "raster"] = Field("cycles", description="'cycles': Blender's path tracer; 'raster': MuJoCo's OpenGL renderer, milliseconds a frame, for tests and previews.")
    # Denoised, one sample is all the detector needs, at a thirtieth of 128's cost (docs/stages/render.md, quality).
    samples: Count(1, 65536) = Field(1, description="Cycles path-tracing samples per pixel.")
    adaptive_threshold: Fraction = Field(0.05, description="Cycles adaptive sampling noise threshold; 0 turns adaptive sampling off.")
    denoise: bool = Field(True, description="Denoise each frame with OpenImageDenoise.")
    denoise_quality: Literal["fast", "balanced", "high"] = Field(
        "fast", description="OpenImageDenoise effort; 'high' (accurate prefilter) costs about 3 s more per 640x480 frame on 2 cores."
    )
    bounces: BouncesConfig = Field(BouncesConfig(), description="Cycles' light-path bounce limits.")
    persistent_data: bool = Field(True, description="Keep Blender's scene data between frames.")
    threads: Count(0, 1024) = Field(0, description="Render threads; 0 means all cores.")
    device: Literal["cpu", "gpu", "auto"] = Field(
        "cpu", description="Where Cycles path-traces: 'cpu'; 'gpu': an NVIDIA GPU through OptiX or CUDA, refused when none "
        "answers; 'auto': the GPU when one answers, else the CPU. Speed only: render.json does not record it.")
    depth_noise: DepthNoiseConfig = Field(DepthNoiseConfig(), description="Noise model of the depth image.")
    raster: RasterConfig = Field(RasterConfig(), description="The raster backend's shadows and antialiasing.")


class DetectorConfig(Strict):
    model: Path | None = Field(None, description="ONNX model; null means the one shipped in the package.")
    input_size: Count(64, 2048) = Field(320, description="Side of the square network input, px.")
    score_threshold: Fraction = Field(0.68, description="Score a detection needs. Fused scores run higher than one "
                                      "pass's: 0.68 gave at most 5 % false detections on held-out paper runs "
                                      "(docs/stages/perception.md).")
    windows: tuple[Annotated[str, Field(pattern=f"^{LAYOUT_PATTERN}$")], ...] = Field(
        ("2x2", "3x2"), max_length=64,  # the 8 x 8 possible layouts
        description="Also search the overlapping windows of these columns x rows layouts of each frame, "
        "where small fruit look larger (one network pass a window; perception/tiling.py); []: the whole frame only.")
    mirror: bool = Field(True, description="Also search the frame mirrored left to right, the passes fused: one more "
                         "network pass, for recall at the same rate of false detections (docs/stages/perception.md).")

    @model_validator(mode="before")
    @classmethod
    def _grid_of_older_runs(cls, data: Any) -> Any:
        """Run directories written before the window layouts say `grid: N`, meaning N x N windows."""
        if isinstance(data, dict) and "grid" in data and "windows" not in data:
            data = dict(data)
            grid = data.pop("grid")
            data["windows"] = [] if grid == 1 else [f"{grid}x{grid}"]
        return data

    @property
    def layouts(self) -> list[Layout]:
        return [layout(text) for text in self.windows]


class IntervalConfig(Strict):
    """The interval of each plant's ripe count (renderloop.counting.uncertainty): every counted cluster is a real
    fruit (weak ones with probability `weak_real`), plus hidden fruit ~ Poisson(hidden + hidden_per_lone x lone
    detections + hidden_unseen x unseen fraction), mixed over redraws of the random fixed set. weak_real, hidden and
    hidden_per_lone are fitted by benchmarks/intervals.py on demo runs; the greenhouse preset has its own fit
    (docs/stages/counting.md)."""

    level: Real(0.5, 0.999) = Field(0.9, description="Probability the interval holds the true count (its central quantiles).")
    redraws: Count(1, 64) = Field(
        8, description="Counts of each row the interval mixes: the estimate and redraws - 1 redraws of the random fixed "
        "set, each costing as much as counting the ripe rows again.")
    weak_margin: Real(1.0, 100.0) = Field(
        2.0, description="A cluster of fewer points than weak_margin x MinPts is weakly supported (2: fewer than twice "
        "the views a fruit needs).")
    min_spread: Real(0.0, math.pi) = Field(
        0.35, description="A cluster whose view directions (its centre to the cameras) all lie within this angle of "
        "one another was seen from one side only, and is weak, rad.")
    weak_real: Fraction = Field(1.0, description="Probability that a weak cluster is a real ripe fruit of its plant.")
    hidden: Real(0.0, 100.0) = Field(
        0.02, description="Expected ripe fruit of a plant that no cluster stands for, however well it was seen.")
    hidden_per_lone: Real(0.0, 100.0) = Field(
        0.3, description="Expected hidden ripe fruit added by each lone detection of the plant: one in no cluster and "
        "farther than 2 eps from every counted fruit, a fruit seen once.")
    hidden_unseen: Real(0.0, 1000.0) = Field(
        4.0, description="Expected hidden ripe fruit of a plant whose canopy box no depth frame has seen, scaled by the "
        "unseen fraction; a prior (about the ripe fruit a demo or paper plant bears), not fitted.")


class CountingConfig(Strict):
    """Yield counting (OPTICS on the multi-view fruit points of each row) and the harvest plan."""

    points: Count(2, 100_000) = Field(500, description="Size of the fixed point set OPTICS clusters per row and class.")
    eps: Real(0.001, 1.0) = Field(0.04, description="OPTICS neighbourhood (eps and max_eps), m: about one pepper.")
    augment_noise_std: Real(0.0, 1.0) = Field(0.01, description="Sigma of the gaussian copies that fill a row up to `points`, m.")
    use_layout: bool = Field(True, description="Assign and filter points by the plant volumes; false: nearest table and LocalOutlierFactor.")
    expected_per_plant: Count(1, 1000) = Field(
        10, description="Fruit a plant may bear (the paper's 10); informational, the counting itself does not use it."
    )
    volume_margin: Real(0.0, 1.0) = Field(0.02, description="Growth of each plant's bounding box before points are tested against it, m.")
    min_views: Count(2, 1000) = Field(2, description="Detections a pepper needs; MinPts = min_views * ceil(points / n_init).")
    lone_credit: Fraction = Field(
        0.0, description="Ripe fruit each lone detection (a fruit seen once: one detection in no cluster, farther than "
        "2 eps from every counted fruit) adds to its plant's estimate, rounded per plant. 0: the paper's count, clusters "
        "only. A sparse scan sees many real fruit once, a dense one sees a real fruit again: fit it per scan "
        "(benchmarks/intervals.py).")
    cluster_method: Literal["dbscan", "xi"] = Field("dbscan", description="OPTICS cluster extraction (scikit-learn).")
    xi: Real(0.0, 1.0, low_open=True, high_open=True) = Field(0.05, description="Steepness for cluster_method 'xi'.")
    lof_neighbors: Count(2, 1000) = Field(
        4, description="LocalOutlierFactor n_neighbors when use_layout is false; keep it below the fewest views of a fruit."
    )
    harvest_min_ripe: Count(1, 1000) = Field(1, description="Ripe fruit a plant must be expected to bear to be brought to the workstation.")
    interval: IntervalConfig = Field(IntervalConfig(), description="The interval of each plant's, row's and the total ripe count.")


class AdaptiveConfig(Strict):
    """The adaptive mission: a coarse pass over every plant, then re-scans of the plants whose count is uncertain."""

    first_pass_rate_hz: Real(0.01, MAX_CAMERA_RATE_HZ) = Field(
        0.5, description="Camera rate of the coarse first pass (the static scan's path), Hz.")
    views_per_round: Count(1, 50) = Field(3, description="Most views added to one plant in one re-scan.")
    rounds: Count(1, 10) = Field(2, description="Most re-scans of one plant.")
    budget_s: Real(0.0, 3600.0) = Field(
        20.0, description="Flight time the re-scans of one plant may add, s; 0 flies the first pass only.")
    voxel: Real(0.005, 0.2) = Field(0.02, description="Edge of a cell of the voxel map built from the depth frames, m.")
    min_gain: Count(0, 1_000_000) = Field(
        20, description="Unknown cells of the canopy a view must newly see to be worth flying to (an uncertain fruit "
        "it sees counts as a whole canopy's worth).")
    interval: IntervalConfig | None = Field(
        None, description="The interval of the count of an adaptive run (counts.json), fitted on adaptive runs: their "
        "counts rest on views chosen where the first pass was unsure. None: counting.interval. The mission's own "
        "decisions always use counting.interval: they are taken on a scan as sparse as the first pass.")
    lone_credit: Fraction | None = Field(
        None, description="counting.lone_credit of an adaptive run's count (counts.json), fitted on adaptive runs; "
        "None: counting.lone_credit. The mission's own decisions use counting.lone_credit.")


class MissionConfig(Strict):
    """How the scan is flown."""

    kind: Literal["static", "adaptive"] = Field(
        "static", description="static: the planned scan at the camera's rate. adaptive: a coarse first pass at "
        "mission.adaptive.first_pass_rate_hz, then re-scans of uncertain plants from next-best views (always online).")
    online: bool = Field(False, description="Render and detect while flying (the simulation steps, the camera renders "
                         "at its instants, perception runs on each frame as it arrives); same files and counts as the "
                         "batch stages fly, render, detect.")
    adaptive: AdaptiveConfig = Field(AdaptiveConfig(), description="The adaptive mission's settings.")


class Config(Strict):
    seed: Count(0, 2**63 - 1) = Field(0, description="Seed of every random draw of the run (scene, noise, sampling).")
    greenhouse: GreenhouseConfig = Field(GreenhouseConfig(), description="Room, tables and workstation.")
    plants: PlantConfig = Field(PlantConfig(), description="Procedural plants and their fruit.")
    robot: RobotConfig = Field(RobotConfig(), description="The aerial manipulator.")
    camera: CameraConfig = Field(CameraConfig(), description="The RGB-D camera on the arm's tip.")
    planner: PlannerConfig = Field(PlannerConfig(), description="Scan waypoints and trajectory limits.")
    controller: ControllerConfig = Field(ControllerConfig(), description="Flight and arm control, and the physics step.")
    renderer: RendererConfig = Field(RendererConfig(), description="Rendering of the camera frames.")
    detector: DetectorConfig = Field(DetectorConfig(), description="The pepper detector.")
    counting: CountingConfig = Field(CountingConfig(), description="Yield counting and the harvest plan.")
    mission: MissionConfig = Field(MissionConfig(), description="How the scan is flown (batch stages, or the loop online).")

    @model_validator(mode="after")
    def _fits(self) -> Config:
        total = len(self.greenhouse.tables) * self.greenhouse.plants_per_table
        if self.plants.bearing is not None and self.plants.bearing > total:
            raise ValueError(f"plants.bearing: {self.plants.bearing} bearing plants but the greenhouse has {total}")
        if total * self.plants.most_leaves > MAX_LEAVES:
            raise ValueError(f"{self.plants.leaves_field}: {total} plants of up to {self.plants.most_leaves} leaves are more than {MAX_LEAVES} leaves")
        if self.camera.rate_hz > self.controller.rate_hz:
            raise ValueError(f"camera.rate_hz: frames are taken at control ticks, so {self.camera.rate_hz:g} Hz cannot be "
                             f"served by a {self.controller.rate_hz:g} Hz controller")
        return self

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.model_dump(mode="json"), sort_keys=False, default_flow_style=None)


def config_schema() -> dict[str, Any]:
    """JSON schema of the whole config: every field with its description, default and bounds."""
    return Config.model_json_schema()


PRESETS = ("demo", "paper", "greenhouse")


def _read_yaml_mapping(text: str, source: str) -> dict[str, Any]:
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise UserError(f"{source}: not valid YAML{where}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise UserError(f"{source}: expected a mapping of config sections, got {type(data).__name__}")
    return data


def preset_overrides(name: str) -> dict[str, Any]:
    if name not in PRESETS:
        raise UserError(f"unknown preset {name!r} (choose from: {', '.join(PRESETS)})")
    text = resources.files("renderloop.presets").joinpath(f"{name}.yaml").read_text(encoding="utf-8")
    return _read_yaml_mapping(text, f"preset {name}")


def read_config_file(path: Path) -> dict[str, Any]:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else "not a UTF-8 text file"
        raise UserError(f"{path}: cannot read config ({reason})") from None
    return _read_yaml_mapping(text, str(path))


def deep_merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """Override wins field by field; nested sections merge instead of being replaced whole."""
    merged = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = deep_merge(merged[key], value)
        else:
            merged[key] = value
    return merged


def validate(data: dict[str, Any], source: str) -> Config:
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        raise UserError(f"{source}: {problem(exc)}") from None


def load_config(preset: str = "demo", config_file: Path | None = None, seed: int | None = None,
                online: bool | None = None, mission: str | None = None) -> Config:
    """Preset, then the user's YAML over it, then the command line (seed, --online, --mission) over both."""
    data = preset_overrides(preset)
    source = f"preset {preset}"
    if config_file is not None:
        data = deep_merge(data, read_config_file(config_file))
        source = str(config_file)
    if seed is not None:
        data = deep_merge(data, {"seed": seed})
    if online is not None:
        data = deep_merge(data, {"mission": {"online": online}})
    if mission is not None:
        data = deep_merge(data, {"mission": {"kind": mission}})
    return validate(data, source)


def load_resolved(path: Path) -> Config:
    """Read a run directory's `config.yaml` (already complete, so no preset underneath)."""
    return validate(read_config_file(path), str(path))
