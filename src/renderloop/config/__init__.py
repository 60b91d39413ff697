"""Typed configuration of a run: one pydantic model per subsystem, presets, YAML in and out.

`Config` and the loading are here; the sections live by subsystem (`scene`, `flight`, `camera`, `perception`,
`mission`) on the building blocks of `fields`, and every model is importable from `renderloop.config`. `training`
and `dataset` hold the settings of `renderloop train` and `renderloop dataset`, bounded the same way but outside a
run's `Config`. A config is changed
with `Config.override`, which validates the change as a config file is validated.

The defaults are the numbers of the reference work (docs/design.md), so the `paper`
preset is almost empty; `demo` shrinks the greenhouse to one table. A user YAML
file is deep-merged over the preset, and every unknown key is an error, because a
misspelt field that silently keeps its default is the worst kind of config bug.
"""

from __future__ import annotations

import typing
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, Field, ValidationError, model_validator
from pydantic_core import to_jsonable_python

from renderloop.config.camera import BouncesConfig, CameraConfig, DepthNoiseConfig, RasterConfig, RendererConfig, SensorConfig
from renderloop.config.fields import MAX_LEAVES, Count, Strict
from renderloop.config.flight import PID, ArmConfig, ControllerConfig, PlannerConfig, RobotConfig, RotorConfig
from renderloop.config.mission import AdaptiveConfig, MissionConfig
from renderloop.config.perception import CountingConfig, DetectorConfig, IntervalConfig
from renderloop.config.dataset import DatasetSpec
from renderloop.config.training import TrainSettings
from renderloop.config.scene import (
    RIPE_COLORS,
    EnvironmentConfig,
    GreenhouseConfig,
    HighWireConfig,
    PepperConfig,
    PepperStyleConfig,
    PlantConfig,
    PotConfig,
)
from renderloop.errors import UserError, did_you_mean, problem
from renderloop.io.bounded import load_yaml

__all__ = [
    "PID", "PRESETS", "RIPE_COLORS", "AdaptiveConfig", "ArmConfig", "BouncesConfig",
    "CameraConfig", "Config", "ControllerConfig", "CountingConfig", "DatasetSpec", "DepthNoiseConfig", "DetectorConfig",
    "EnvironmentConfig", "GreenhouseConfig", "HighWireConfig", "IntervalConfig", "MissionConfig", "PepperConfig",
    "PepperStyleConfig", "PlannerConfig", "PlantConfig", "PotConfig", "RasterConfig", "RendererConfig", "RobotConfig",
    "RotorConfig", "SensorConfig", "TrainSettings", "choices", "config_schema", "deep_merge", "describe_changes",
    "load_config", "load_resolved", "preset_overrides",
    "read_config_file", "validate",
]


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
        grown = min(total, self.plants.prototypes)  # more plants than prototypes: copies, whose leaves are their prototype's
        if grown * self.plants.most_leaves > MAX_LEAVES:
            raise ValueError(f"{self.plants.leaves_field}: {grown} plants of up to {self.plants.most_leaves} leaves are more than {MAX_LEAVES} leaves")
        rows, row = len(self.greenhouse.tables), self.planner.row
        if row is not None and row >= rows:
            raise ValueError(f"planner.row: the greenhouse has {rows} rows (0 to {rows - 1}), not {row}")
        if self.mission.uavs > 1 and self.mission.split != "rows":
            raise ValueError(f"mission.uavs: {self.mission.uavs} UAVs share a scan split by rows; set mission.split: rows")
        if self.camera.rate_hz > self.controller.rate_hz:
            raise ValueError(f"camera.rate_hz: frames are taken at control ticks, so {self.camera.rate_hz:g} Hz cannot be "
                             f"served by a {self.controller.rate_hz:g} Hz controller")
        return self

    def override(self, patch: dict[str, Any], source: str | None = None) -> Config:
        """A new config: `patch` deep-merged over this one's fields, then validated as a config file is, so a value out
        of its range or a key no field has is the one-line UserError the CLI prints (`source: field: problem`, or
        `field: problem` without a source). A model in the patch is validated again as its fields."""
        return validate(deep_merge(self.model_dump(mode="json"), to_jsonable_python(patch)), source)

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.model_dump(mode="json"), sort_keys=False, default_flow_style=None)


def choices(model: type[BaseModel], name: str) -> tuple[str, ...]:
    """The values the `Literal` field `name` of `model` allows, in the order its type lists them: a command-line option
    of the same values reads them here, so they are written once."""
    values = typing.get_args(model.model_fields[name].annotation)
    if not values or not all(isinstance(value, str) for value in values):
        raise TypeError(f"{model.__name__}.{name} is not a choice of names")
    return values


def _changes(old: Any, new: Any, path: str) -> Iterator[tuple[str, Any, Any]]:
    """(dotted path, old value, new value) of every leaf that differs; lists of one length are compared item by item."""
    if isinstance(old, dict) and isinstance(new, dict):
        for key in [*old, *(key for key in new if key not in old)]:
            if old.get(key) != new.get(key):
                yield from _changes(old.get(key), new.get(key), f"{path}.{key}" if path else str(key))
    elif isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        for index, (a, b) in enumerate(zip(old, new)):
            if a != b:
                yield from _changes(a, b, f"{path}.{index}")
    else:
        yield path, old, new


def _short(value: Any, width: int = 40) -> str:
    text = yaml.safe_dump(value, default_flow_style=True, width=10**6).strip().removesuffix("...").strip()
    return text if len(text) <= width else text[: width - 3] + "..."


def describe_changes(old: Config, new: Config, most: int = 5) -> str:
    """The fields whose values differ between two configs, as `seed: 0 -> 8; camera.rate_hz: 5.0 -> 0.5`: the first
    `most`, then how many more."""
    found = list(_changes(old.model_dump(mode="json"), new.model_dump(mode="json"), ""))
    shown = "; ".join(f"{path}: {_short(a)} -> {_short(b)}" for path, a, b in found[:most])
    return shown + (f"; and {len(found) - most} more" if len(found) > most else "")


def config_schema() -> dict[str, Any]:
    """JSON schema of the whole config: every field with its description, default and bounds."""
    return Config.model_json_schema()


PRESETS = ("demo", "paper", "greenhouse", "commercial")

# Fields a config no longer has, and why. A user's file that sets one is told so in one line; a run directory's
# config.yaml, written whole by an older version, loads without them (what they held was never read).
REMOVED = {("detector", "input_size"): "a detector runs at the input size of its ONNX model"}


def _read_yaml_mapping(text: str, source: str) -> dict[str, Any]:
    data = load_yaml(text, source)  # depth and size bounded before parsing: one line, never a RecursionError
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise UserError(f"{source}: expected a mapping of config sections, got {type(data).__name__}")
    return data


def preset_overrides(name: str) -> dict[str, Any]:
    if name not in PRESETS:
        raise UserError(f"unknown preset {name!r} (choose from: {', '.join(PRESETS)}){did_you_mean(name, PRESETS)}")
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


def _without_removed(data: dict[str, Any], source: str | None, written: bool) -> dict[str, Any]:
    for (section, key), why in REMOVED.items():
        if isinstance(data.get(section), dict) and key in data[section]:
            if not written:
                found = f"{section}.{key}: no longer a setting ({why}); remove it"
                raise UserError(f"{source}: {found}" if source else found)
            data = {**data, section: {name: value for name, value in data[section].items() if name != key}}
    return data


def validate(data: dict[str, Any], source: str | None, written: bool = False) -> Config:
    """`data` as a Config; `written`: a whole config a run directory holds, which may carry fields since removed."""
    data = _without_removed(data, source, written)
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        found = problem(exc, Config)  # an unknown key names the closest field of its section
        raise UserError(f"{source}: {found}" if source else found) from None


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
    return validate(read_config_file(path), str(path), written=True)
