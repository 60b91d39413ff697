"""`renderloop dataset` builds its DatasetSpec from the options given, over the model's defaults, and a bad value is
one line naming the field."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import cli

from renderloop.config.dataset import DatasetSpec
from renderloop.dataset import build


def _given(monkeypatch, capsys, tmp_path: Path, *options: str) -> tuple[int, str, list]:
    specs = []
    monkeypatch.setattr(build, "build_dataset", lambda out, images, spec, *_: specs.append(spec) or 0)
    code, _, stderr = cli(monkeypatch, capsys, "dataset", "--out", str(tmp_path / "set"), "--images", "4", *options)
    return code, stderr, specs


def test_the_dataset_command_takes_its_defaults_from_the_spec_and_only_given_options_change_them(
        monkeypatch, capsys, tmp_path: Path):
    code, stderr, specs = _given(monkeypatch, capsys, tmp_path)
    assert code == 0, stderr
    assert specs == [DatasetSpec()]
    code, stderr, specs = _given(monkeypatch, capsys, tmp_path, "--width", "64", "--styles", "pepper,simple",
                                 "--distance", "0.4", "0.9", "--clutter", "--close", "0.5")
    assert code == 0, stderr
    assert specs == [DatasetSpec(width=64, height=48, styles=("pepper", "simple"), distance=(0.4, 0.9), clutter=True,
                                 close=0.5)]


@pytest.mark.parametrize(("options", "sentence"), [
    (["--sensor", "1.5"], "dataset: sensor: Input should be less than or equal to 1"),
    (["--distance", "0.9", "0.4"], "dataset: distance: near 0.9 m is beyond far 0.4 m"),
    (["--environments", "forest"], "dataset: environments.0: Input should be 'plain' or 'film'"),
    (["--views-per-scene", "0"], "dataset: views_per_scene: Input should be greater than or equal to 1"),
])
def test_a_bad_dataset_option_is_one_line_naming_the_field_and_nothing_is_made(monkeypatch, capsys, tmp_path: Path,
                                                                            options, sentence):
    code, stderr, specs = _given(monkeypatch, capsys, tmp_path, *options)
    assert code == 2 and stderr.strip() == f"renderloop: error: {sentence}" and not specs
    assert not (tmp_path / "set").exists()
