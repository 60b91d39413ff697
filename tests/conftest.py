"""Shared fixtures: generated scenes are cached per session because several tests read them."""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import pytest

from renderloop.cli import main
from renderloop.config import Config, load_config
from renderloop.planning.stage import run_plan
from renderloop.scene.generate import generate_scene
from renderloop.scene.model import Scene
from renderloop.scene.stage import run_scene
from renderloop.sim.stage import run_fly


@functools.cache
def scene_for(preset: str, seed: int) -> tuple[Config, Scene]:
    config = load_config(preset, seed=seed)
    return config, generate_scene(config)


@pytest.fixture(scope="session")
def paper() -> tuple[Config, Scene]:
    return scene_for("paper", 7)


@pytest.fixture(scope="session")
def demo() -> tuple[Config, Scene]:
    return scene_for("demo", 0)


@pytest.fixture(scope="session")
def paper_run(tmp_path_factory) -> tuple[Config, Path]:
    """The paper scenario planned and flown once (about 15 s): the closed-loop figures are read from it."""
    config = load_config("paper", seed=7)
    run_dir = tmp_path_factory.mktemp("paper7")
    run_scene(run_dir, config)
    run_plan(run_dir, config)
    run_fly(run_dir, config)
    return config, run_dir


def fly_demo_raster(run_dir: Path, rate_hz: float = 0.25) -> Path:
    """The demo scenario planned and flown, set to render with the raster backend at a few frames."""
    data = load_config("demo").model_dump(mode="json")
    data["renderer"]["backend"] = "raster"
    data["camera"]["rate_hz"] = rate_hz
    config = Config.model_validate(data)
    run_scene(run_dir, config)
    run_plan(run_dir, config)
    run_fly(run_dir, config)
    return run_dir


@pytest.fixture(scope="session")
def complete_run(tmp_path_factory) -> Path:
    """The demo scenario through every stage up to count, raster frames every 4 s: a test copies it before changing it."""
    from renderloop.counting.stage import run_count
    from renderloop.perception.stage import run_detect
    from renderloop.render.stage import run_render
    from renderloop.rundir.files import read_config

    run_dir = fly_demo_raster(tmp_path_factory.mktemp("complete") / "run")
    config = read_config(run_dir)
    run_render(run_dir, config)
    run_detect(run_dir, config)
    run_count(run_dir, config)
    return run_dir


def cli(monkeypatch, capsys, *args: str) -> tuple[int, str, str]:
    """Run the real entry point in-process: exit code, stdout, stderr."""
    monkeypatch.setattr(sys, "argv", ["renderloop", *args])
    with pytest.raises(SystemExit) as ended:
        main()
    captured = capsys.readouterr()
    return ended.value.code or 0, captured.out, captured.err


def jittered_model(seed: int):
    """A random detector network whose scores differ between anchors (a fresh head scores every anchor alike)."""
    import torch

    from renderloop.perception.training.ssd import build_model

    torch.manual_seed(seed)
    model = build_model().eval()
    with torch.no_grad():
        for parameter in model.parameters():
            parameter.add_(torch.randn_like(parameter) * 0.05)
    return model
