from __future__ import annotations

from pathlib import Path

import pytest

from renderloop.config import Config, load_config, load_resolved
from renderloop.errors import UserError


def test_paper_preset_is_the_reference_scenario():
    config = load_config("paper")
    assert len(config.greenhouse.tables) == 8 and config.greenhouse.plants_per_table == 4
    assert config.plants.bearing == 20
    assert config.plants.peppers.per_side == (1, 5)
    assert dict(config.plants.peppers.colors) == {"red": 1.0}
    assert config.camera.fx == pytest.approx(589.4, abs=0.1)


def test_demo_preset_is_one_table_all_bearing():
    config = load_config("demo")
    assert len(config.greenhouse.tables) == 1 and config.greenhouse.plants_per_table == 4
    assert config.plants.bearing is None


def test_the_commercial_preset_detects_as_the_greenhouse_preset_its_crop_and_camera():
    """The detector's threshold is chosen on the greenhouse preset's scans; the commercial compartment is the same
    crop seen by the same camera (two passes a frame), so it must take the same setting."""
    greenhouse, commercial = load_config("greenhouse"), load_config("commercial")
    assert commercial.plants.style == greenhouse.plants.style
    assert (commercial.camera.width, commercial.camera.height) == (greenhouse.camera.width, greenhouse.camera.height)
    assert commercial.detector == greenhouse.detector != load_config("paper").detector

def test_yaml_overrides_nested_fields_and_keeps_the_rest(tmp_path: Path):
    override = tmp_path / "override.yaml"
    override.write_text("plants:\n  peppers:\n    per_side: [2, 3]\ncamera:\n  rate_hz: 10\n")
    config = load_config("paper", override, seed=3)
    assert config.seed == 3
    assert config.plants.peppers.per_side == (2, 3)
    assert config.plants.peppers.colors == {"red": 1.0}  # untouched sibling of the overridden field
    assert config.camera.rate_hz == 10 and config.camera.width == 640


def test_resolved_config_round_trips_through_yaml(tmp_path: Path):
    config = load_config("demo", seed=11)
    path = tmp_path / "config.yaml"
    path.write_text(config.to_yaml())
    assert load_resolved(path) == config


def test_a_run_directory_config_written_with_a_removed_field_loads_as_the_same_config(tmp_path: Path):
    config = load_config("demo", seed=11)
    path = tmp_path / "config.yaml"
    path.write_text(config.to_yaml().replace("detector:\n", "detector:\n  input_size: 320\n", 1))
    assert "input_size: 320" in path.read_text()
    assert load_resolved(path) == config


@pytest.mark.parametrize(
    ("yaml_text", "message"),
    [
        ("greenhouse:\n  tabels: []\n", "greenhouse.tabels: unknown field"),
        ("greenhouse:\n  plants_per_table: 0\n", "greenhouse.plants_per_table"),
        ("plants:\n  bearing: -1\n", "plants.bearing"),
        ("plants:\n  peppers:\n    per_side: [5, 1]\n", "per_side: minimum 5 is larger than maximum 1"),
        ("plants:\n  bearing: 40\n", "plants.bearing: 40 bearing plants but the greenhouse has 32"),
        ("planner:\n  velocity_limits: [1, 1, 1, 1, 1, 1, 0]\n", "planner.velocity_limits"),
        ("camera:\n  clip: [5, 1]\n", "camera: clip: near must be smaller than far"),
        ("robot:\n  mass: .nan\n", "robot.mass"),
        ("detector:\n  windows: [2x2, 3x9]\n", "detector.windows.1"),
        ("detector:\n  input_size: 448\n", "detector.input_size: no longer a setting (a detector runs at the input size"),
        ("- just\n- a list\n", "expected a mapping"),
        ("greenhouse: [unclosed\n", "not valid YAML"),
    ],
)
def test_bad_config_is_one_line_naming_the_field(tmp_path: Path, yaml_text: str, message: str):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml_text)
    with pytest.raises(UserError) as error:
        load_config("paper", path)
    assert message in str(error.value)
    assert "\n" not in str(error.value)


def test_unknown_preset_and_missing_file():
    with pytest.raises(UserError, match="unknown preset 'nope'"):
        load_config("nope")
    with pytest.raises(UserError, match="cannot read config"):
        load_config("demo", Path("/nonexistent/config.yaml"))


def test_defaults_validate():
    assert Config().greenhouse.plant_spacing == 0.5
