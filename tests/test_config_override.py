"""One validated way to change a config: `Config.override`, and the `train` settings bounded beside the config."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from conftest import cli
from pydantic import ValidationError

from renderloop.config import SensorConfig, TrainSettings, load_config
from renderloop.errors import UserError


def test_an_override_merges_nested_sections_and_keeps_every_other_field():
    config = load_config("paper")
    changed = config.override({"seed": 5, "camera": {"width": 160, "sensor": {"enabled": True}},
                               "plants": {"peppers": {"per_side": (2, 3)}}})
    assert (changed.seed, changed.camera.width, changed.camera.sensor.enabled) == (5, 160, True)
    assert changed.plants.peppers.per_side == (2, 3) and changed.plants.peppers.colors == config.plants.peppers.colors
    assert changed.camera.height == config.camera.height and changed.camera.sensor.gain == config.camera.sensor.gain
    assert changed.model_dump(exclude={"seed", "camera", "plants"}) == config.model_dump(exclude={"seed", "camera", "plants"})


def test_an_override_is_a_new_frozen_config_and_leaves_the_original_as_it_was():
    config = load_config("demo")
    changed = config.override({"controller": {"rate_hz": 250.0}})
    assert changed is not config and changed.controller.rate_hz == 250.0
    assert config == load_config("demo")
    with pytest.raises(ValidationError, match="frozen"):
        changed.seed = 3


def test_an_override_out_of_range_is_the_one_line_a_config_file_gets(tmp_path: Path):
    path = tmp_path / "fast.yaml"
    path.write_text("controller:\n  rate_hz: 5000\n", encoding="utf-8")
    with pytest.raises(UserError) as from_file:
        load_config("demo", path)
    with pytest.raises(UserError) as refused:
        load_config("demo").override({"controller": {"rate_hz": 5000}})
    assert str(refused.value) == "controller.rate_hz: Input should be less than or equal to 1000"
    assert str(from_file.value) == f"{path}: {refused.value}"
    with pytest.raises(UserError, match=r"^PepperScanEnv config: camera.rate_hz: frames are taken at control ticks"):
        load_config("demo").override({"camera": {"rate_hz": 60.0}, "controller": {"rate_hz": 50.0}}, "PepperScanEnv config")


@pytest.mark.parametrize(("patch", "sentence"), [
    ({"camera": {"widht": 160}}, "camera.widht: unknown field; did you mean camera.width?"),
    ({"cameras": {"width": 160}}, "cameras: unknown field; did you mean camera?"),
    ({"plants": {"peppers": {"per_sides": (2, 3)}}}, "plants.peppers.per_sides: unknown field; did you mean plants.peppers.per_side?"),
])
def test_an_override_refuses_a_key_no_field_has(patch: dict, sentence: str):
    with pytest.raises(UserError) as refused:
        load_config("demo").override(patch)
    assert str(refused.value) == sentence


def test_a_section_changed_without_validation_is_validated_when_patched_in():
    config = load_config("demo")
    unchecked = config.controller.model_copy(update={"rate_hz": math.nan})
    with pytest.raises(UserError, match=r"^controller.rate_hz: Input should be a finite number$"):
        config.override({"controller": unchecked})
    sensor = config.override({"camera": {"sensor": SensorConfig(enabled=True)}})
    assert sensor.camera.sensor == SensorConfig(enabled=True)


def test_train_takes_its_defaults_from_the_settings_model(monkeypatch, capsys, tmp_path: Path):
    train = pytest.importorskip("renderloop.perception.training.train")  # the train extra
    given = []
    monkeypatch.setattr(train, "train_detector", lambda datasets, out, settings, *_, **__: given.append(settings) or {"history": []})
    code, _, stderr = cli(monkeypatch, capsys, "train", str(tmp_path), "--out", str(tmp_path / "m.onnx"), "--epochs", "3")
    assert code == 0, stderr
    assert given == [TrainSettings(epochs=3)]


@pytest.mark.parametrize(("option", "sentence"), [
    (["--epochs", "0"], "train: epochs: Input should be greater than or equal to 1"),
    (["--learning-rate", "2"], "train: learning_rate: Input should be less than or equal to 1"),
    (["--batch-size", "5000"], "train: batch_size: Input should be less than or equal to 4096"),
])
def test_train_refuses_a_setting_out_of_its_range_in_one_line(monkeypatch, capsys, tmp_path: Path, option: list[str],
                                                              sentence: str):
    pytest.importorskip("renderloop.perception.training.train")  # the train extra
    code, _, stderr = cli(monkeypatch, capsys, "train", str(tmp_path), "--out", str(tmp_path / "m.onnx"), *option)
    assert code == 2 and stderr.strip().splitlines() == [f"renderloop: error: {sentence}"]
    assert not any(tmp_path.iterdir())
