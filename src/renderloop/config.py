"""Typed configuration of a run: one pydantic model per subsystem, presets, YAML in and out.

The defaults are the numbers of the reference work (DESIGN §4), so the `paper`
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

from renderloop.errors import UserError, field_path
from renderloop.perception.tiling import LAYOUT_PATTERN, Layout, layout

PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
PositiveInt = Annotated[int, Field(gt=0, le=1_000_000)]
NonNegativeInt = Annotated[int, Field(ge=0, le=1_000_000)]
Vec2 = tuple[FiniteFloat, FiniteFloat]
Vec3 = tuple[FiniteFloat, FiniteFloat, FiniteFloat]
PositiveVec3 = tuple[PositiveFloat, PositiveFloat, PositiveFloat]

PEPPER_COLORS = ("red", "yellow", "orange", "green")
RIPE_COLORS = frozenset({"red", "yellow", "orange"})


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _ordered_range(value: tuple[float, float], name: str) -> None:
    if value[0] > value[1]:
        raise ValueError(f"{name}: minimum {value[0]} is larger than maximum {value[1]}")


class GreenhouseConfig(Strict):
    """Room, tables (one row of plants each) and the manipulator workstation."""

    size: PositiveVec3 = (12.0, 10.0, 3.5)
    tables: list[Vec2] = Field(
        default=[(x, y) for y in (-2.5, 2.5) for x in (-3.0, -1.0, 1.0, 3.0)],
        min_length=1,
        description="Table centres (x, y); each table is one row of plants along y.",
    )
    table_size: PositiveVec3 = (0.5, 2.0, 0.6)
    plants_per_table: PositiveInt = 4
    plant_spacing: PositiveFloat = 0.5
    workstation_center: Vec2 = (0.0, 0.0)
    workstation_size: PositiveVec3 = (0.5, 1.0, 0.6)

    @model_validator(mode="after")
    def _tables_fit(self) -> GreenhouseConfig:
        length = self.table_size[1]
        if (self.plants_per_table - 1) * self.plant_spacing > length + 1e-9:
            raise ValueError(
                f"plants_per_table: {self.plants_per_table} plants {self.plant_spacing} m apart "
                f"do not fit on a {length} m table"
            )
        half_room = (self.size[0] / 2, self.size[1] / 2)
        for x, y in self.tables:
            if abs(x) + self.table_size[0] / 2 > half_room[0] or abs(y) + length / 2 > half_room[1]:
                raise ValueError(f"tables: table at ({x}, {y}) lies outside the {self.size[0]} x {self.size[1]} m room")
        return self


class PotConfig(Strict):
    radius_top: PositiveFloat = 0.1
    radius_bottom: PositiveFloat = 0.075
    height: PositiveFloat = 0.18


class PepperConfig(Strict):
    """Sweet peppers: blocky lobed fruit about 7-10 cm long."""

    per_side: tuple[PositiveInt, PositiveInt] = (1, 5)
    length: tuple[PositiveFloat, PositiveFloat] = (0.07, 0.10)
    width_ratio: tuple[PositiveFloat, PositiveFloat] = (0.8, 1.0)
    lobes: tuple[Literal[3, 4], Literal[3, 4]] = (3, 4)
    lobe_depth: tuple[NonNegativeFloat, NonNegativeFloat] = (0.05, 0.14)
    max_tilt: NonNegativeFloat = Field(0.35, le=math.pi / 2, description="Hanging axis tilt from vertical, rad.")
    colors: dict[Literal["red", "yellow", "orange", "green"], NonNegativeFloat] = Field(
        default={"red": 1.0}, description="Relative weight of each colour class; green is unripe."
    )

    @model_validator(mode="after")
    def _ranges(self) -> PepperConfig:
        for name in ("per_side", "length", "width_ratio", "lobes", "lobe_depth"):
            _ordered_range(getattr(self, name), name)
        if not self.colors or sum(self.colors.values()) <= 0:
            raise ValueError("colors: at least one colour needs a positive weight")
        return self


class PlantConfig(Strict):
    """Procedural pepper plants: stem, branches, leaves, flowers, fruit, pot."""

    bearing: PositiveInt | None = Field(20, description="Plants bearing fruit; null means every plant.")
    volume: PositiveVec3 = Field((0.44, 0.44, 0.5), description="Canopy box above the pot (x, y, z), m.")
    stem_radius: PositiveFloat = 0.006
    branches: tuple[PositiveInt, PositiveInt] = (2, 4)
    leaves: tuple[PositiveInt, PositiveInt] = (30, 55)
    leaf_length: tuple[PositiveFloat, PositiveFloat] = (0.07, 0.14)
    leaf_width_ratio: tuple[PositiveFloat, PositiveFloat] = (0.4, 0.6)
    leaf_curvature: tuple[NonNegativeFloat, NonNegativeFloat] = (0.0, 12.0)
    flowers: tuple[NonNegativeInt, NonNegativeInt] = (1, 5)
    pot: PotConfig = PotConfig()
    peppers: PepperConfig = PepperConfig()

    @model_validator(mode="after")
    def _ranges(self) -> PlantConfig:
        for name in ("branches", "leaves", "leaf_length", "leaf_width_ratio", "leaf_curvature", "flowers"):
            _ordered_range(getattr(self, name), name)
        return self


class RotorConfig(Strict):
    """Rotor thrust F = kf w^2, drag moment M = km F (DESIGN §4)."""

    kf: PositiveFloat = 8.54858e-6
    km: PositiveFloat = 0.016
    max_speed: PositiveFloat = 1475.0
    time_constant: NonNegativeFloat = Field(0.0, description="First-order motor lag, s; 0 means none.")
    layout: Literal["x", "+"] = "x"


class ArmConfig(Strict):
    """3-DoF pitch chain below the body with the RGB-D camera on its tip."""

    mount: Vec3 = Field((0.0, 0.0, -0.08), description="Joint 1 position in the body frame, m.")
    link_lengths: PositiveVec3 = (0.12, 0.14, 0.3)
    link_masses: PositiveVec3 = (0.05, 0.05, 0.12)
    joint_limits: tuple[FiniteFloat, FiniteFloat] = (-1.6, 1.6)
    nominal_posture: Vec2 = Field((0.0, 0.0), description="q1, q2 that inverse kinematics keeps; q3 sets the pitch.")
    max_torque: PositiveFloat = Field(2.0, description="Joint motor torque limit, N m.")

    @model_validator(mode="after")
    def _limits(self) -> ArmConfig:
        _ordered_range(self.joint_limits, "joint_limits")
        return self


class RobotConfig(Strict):
    mass: PositiveFloat = Field(2.083, description="UAV body mass without the arm, kg.")
    inertia: PositiveVec3 = (0.0827, 0.0827, 0.0104)
    arm_length: PositiveFloat = Field(0.314, description="Body centre to rotor axis, m.")
    prop_radius: PositiveFloat = 0.12
    leg_length: PositiveFloat = Field(0.2, description="Landing legs below the body centre, m.")
    rotor: RotorConfig = RotorConfig()
    arm: ArmConfig = ArmConfig()
    home: Vec3 = Field((0.0, -1.2, 0.0), description="Take-off point on the floor, m.")


class CameraConfig(Strict):
    width: PositiveInt = 640
    height: PositiveInt = 480
    hfov_deg: float = Field(57.0, gt=1, lt=179)
    clip: tuple[PositiveFloat, PositiveFloat] = (0.2, 5.0)
    rate_hz: PositiveFloat = 5.0

    @model_validator(mode="after")
    def _clip(self) -> CameraConfig:
        if self.clip[0] >= self.clip[1]:
            raise ValueError("clip: near must be smaller than far")
        return self

    @property
    def fx(self) -> float:
        return self.width / (2.0 * math.tan(math.radians(self.hfov_deg) / 2.0))


class PlannerConfig(Strict):
    """Elliptical scan waypoints and TOPP-RA limits for q* = (x, y, z, yaw, q1, q2, q3)."""

    distance: PositiveFloat = 1.0
    semi_axes: tuple[PositiveFloat, PositiveFloat] = (0.125, 0.25)
    points_per_ellipse: PositiveInt = 10
    max_camera_pitch: NonNegativeFloat = Field(0.6, le=1.5, description="rad; 0.6 lets the camera aim at the centroid from the ellipse top.")
    velocity_limits: tuple[PositiveFloat, ...] = Field((1.5, 1.5, 0.5, 0.3, 1.0, 1.0, 1.0), min_length=7, max_length=7)
    acceleration_limits: tuple[PositiveFloat, ...] = Field(
        (0.6, 0.6, 0.4, 0.3, 1.2, 1.2, 1.2), min_length=7, max_length=7
    )
    limit_margin: float = Field(0.98, gt=0, le=1, description="Fraction of each limit given to TOPP-RA.")
    sample_rate_hz: PositiveFloat = 100.0


class PID(Strict):
    p: NonNegativeFloat = 0.0
    i: NonNegativeFloat = 0.0
    d: NonNegativeFloat = 0.0
    limit: PositiveFloat | None = None


class ControllerConfig(Strict):
    """Cascade PID gains in SI units, and the loop rates.

    Position loops give velocity (1/s), velocity loops acceleration (m/s² per m/s; the xy
    gains are in rad of tilt per m/s as in the reference work, times g), the attitude loop
    body rates (1/s) and the rate loop angular acceleration (1/s, times the inertia).
    The xy and attitude gains are the authors'; z, rate and joint gains are retuned for
    these units (their rate and z gains acted on rotor-speed units). Joint PIDs act on
    joint acceleration through the arm's mass matrix, with gravity compensation.
    """

    rate_hz: PositiveFloat = Field(100.0, ge=50.0)
    physics_dt: PositiveFloat = Field(0.002, le=0.002)
    position_xy: PID = PID(p=2.0, limit=3.0)
    velocity_xy: PID = PID(p=0.5, i=0.1)
    max_tilt: PositiveFloat = Field(0.6, lt=1.57, description="Largest commanded roll or pitch, rad.")
    position_z: PID = PID(p=4.0, limit=2.0)
    velocity_z: PID = PID(p=8.0, i=3.0)
    attitude: PID = PID(p=7.0)
    rate: PID = PID(p=25.0, i=3.0)
    yaw: PID = PID(p=5.0)
    yaw_rate: PID = PID(p=12.0, i=1.0)
    joints: PID = PID(p=400.0, i=200.0, d=32.0)
    compensate_arm_pitch: bool = Field(True, description="Joint 1 cancels the body's pitch, so the camera holds its planned pitch.")
    position_noise_std: NonNegativeFloat = Field(0.0, description="UWB-like noise on the position fed back, m.")


class DepthNoiseConfig(Strict):
    enabled: bool = True
    sigma_at_1m: NonNegativeFloat = Field(0.002, description="Depth noise sigma at 1 m; grows with z^2.")
    edge_dropout: NonNegativeFloat = Field(0.5, le=1)


class BouncesConfig(Strict):
    """Cycles' light-path limits, for a user trading light transport against time. Samples, not
    bounces, are what a frame costs: 3/1/1/2/2 instead of these saved 6 % at 4 samples on the paper scene."""

    total: NonNegativeInt = 6
    diffuse: NonNegativeInt = 3
    glossy: NonNegativeInt = 3
    transmission: NonNegativeInt = 4
    transparent: NonNegativeInt = 4


class RendererConfig(Strict):
    backend: Literal["cycles", "raster"] = "cycles"
    # chosen by measurement (benchmarks/quality.py, 40 paper frames, 201 findable ripe fruit, shipped detector):
    # ripe recall 0.592 at 1 sample, 0.587 at 2, 0.577 at 4 and 8, 0.582 at 128; false detections 11.2 % at 1,
    # 11.4 % at 128. Denoised, one sample is all the detector needs: 0.94 s a 640x480 frame against 29 s at 128.
    samples: PositiveInt = 1
    adaptive_threshold: NonNegativeFloat = 0.05
    denoise: bool = True
    denoise_quality: Literal["fast", "balanced", "high"] = Field(
        "fast", description="OpenImageDenoise effort; 'high' (accurate prefilter) costs about 3 s more per 640x480 frame on 2 cores."
    )
    bounces: BouncesConfig = BouncesConfig()
    persistent_data: bool = True
    threads: int = Field(0, ge=0, le=1024, description="0 means all cores.")
    depth_noise: DepthNoiseConfig = DepthNoiseConfig()


class DetectorConfig(Strict):
    model: Path | None = Field(None, description="ONNX model; null means the one shipped in the package.")
    input_size: PositiveInt = 320
    score_threshold: float = Field(0.71, ge=0, le=1, description="Score a detection needs. Fused scores run higher than "
                                   "one pass's: 0.71 gave at most 5 % false detections on held-out paper runs (README, Perception).")
    windows: tuple[Annotated[str, Field(pattern=f"^{LAYOUT_PATTERN}$")], ...] = Field(
        ("2x2", "3x2"), description="Also search the overlapping windows of these columns x rows layouts of each frame, "
        "where small fruit look larger (one network pass a window; perception/tiling.py); []: the whole frame only.")
    mirror: bool = Field(True, description="Also search the frame mirrored left to right, the passes fused: one more "
                         "network pass, for recall at the same rate of false detections (README, Perception).")

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


class CountingConfig(Strict):
    """Yield counting (OPTICS on the multi-view fruit points of each row) and the harvest plan."""

    points: PositiveInt = Field(500, ge=2, description="Size of the fixed point set OPTICS clusters per row and class.")
    eps: PositiveFloat = Field(0.04, description="OPTICS neighbourhood (eps and max_eps), m: about one pepper.")
    augment_noise_std: NonNegativeFloat = Field(0.01, description="Sigma of the gaussian copies that fill a row up to `points`, m.")
    use_layout: bool = Field(True, description="Assign and filter points by the plant volumes; false: nearest table and LocalOutlierFactor.")
    expected_per_plant: PositiveInt = Field(
        10, description="Fruit a plant may bear (the paper's 10); informational, the counting itself does not use it."
    )
    volume_margin: NonNegativeFloat = Field(0.02, description="Growth of each plant's bounding box before points are tested against it, m.")
    min_views: PositiveInt = Field(2, ge=2, description="Detections a pepper needs; MinPts = min_views * ceil(points / n_init).")
    cluster_method: Literal["dbscan", "xi"] = Field("dbscan", description="OPTICS cluster extraction (scikit-learn).")
    xi: float = Field(0.05, gt=0, lt=1, description="Steepness for cluster_method 'xi'.")
    lof_neighbors: PositiveInt = Field(
        4, ge=2, description="LocalOutlierFactor n_neighbors when use_layout is false; keep it below the fewest views of a fruit."
    )
    harvest_min_ripe: PositiveInt = Field(1, description="Ripe fruit a plant must be expected to bear to be brought to the workstation.")


class Config(Strict):
    seed: int = Field(0, ge=0, lt=2**63)
    greenhouse: GreenhouseConfig = GreenhouseConfig()
    plants: PlantConfig = PlantConfig()
    robot: RobotConfig = RobotConfig()
    camera: CameraConfig = CameraConfig()
    planner: PlannerConfig = PlannerConfig()
    controller: ControllerConfig = ControllerConfig()
    renderer: RendererConfig = RendererConfig()
    detector: DetectorConfig = DetectorConfig()
    counting: CountingConfig = CountingConfig()

    @model_validator(mode="after")
    def _bearing_fits(self) -> Config:
        total = len(self.greenhouse.tables) * self.greenhouse.plants_per_table
        if self.plants.bearing is not None and self.plants.bearing > total:
            raise ValueError(f"plants.bearing: {self.plants.bearing} bearing plants but the greenhouse has {total}")
        return self

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.model_dump(mode="json"), sort_keys=False, default_flow_style=None)


PRESETS = ("demo", "paper")


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
        error = exc.errors()[0]
        field = field_path(error["loc"]) or "config"
        message = error["msg"].removeprefix("Value error, ")
        if error["type"] == "extra_forbidden":
            message = "unknown field"
        raise UserError(f"{source}: {field}: {message}") from None


def load_config(preset: str = "demo", config_file: Path | None = None, seed: int | None = None) -> Config:
    """Preset, then the user's YAML over it, then the CLI seed over both."""
    data = preset_overrides(preset)
    source = f"preset {preset}"
    if config_file is not None:
        data = deep_merge(data, read_config_file(config_file))
        source = str(config_file)
    if seed is not None:
        data = deep_merge(data, {"seed": seed})
    return validate(data, source)


def load_resolved(path: Path) -> Config:
    """Read a run directory's `config.yaml` (already complete, so no preset underneath)."""
    return validate(read_config_file(path), str(path))
