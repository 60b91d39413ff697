"""What the CLI refuses, the Python API refuses too, in the same one line, before any costly work; and every error the
CLI prints is one line whatever the user's paths hold."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import cli

from renderloop.config import load_config
from renderloop.loop.reference import ReferencePlan
from renderloop.loop.simulation import Simulation
from renderloop.sim.flight import Reference

START = np.array([0.0, -1.2, 1.0, 0.0, 0.0, 0.0, 0.0])  # q* hovering over the demo greenhouse's take-off point


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory) -> Path:
    """A run directory holding the demo scene (the first Simulation makes it; the others find it)."""
    run_dir = tmp_path_factory.mktemp("bounds") / "run"
    Simulation(load_config("demo"), run_dir).close()
    return run_dir


@pytest.fixture
def hovering(demo_dir: Path, monkeypatch):
    """A simulation hovering at START whose planner must not be reached: every refusal comes before TOPP-RA."""
    monkeypatch.setattr(ReferencePlan, "replan", lambda *args: pytest.fail("the planner ran on refused waypoints"))
    with Simulation(load_config("demo"), demo_dir) as sim:
        sim.follow(Reference(np.array([0.0, 0.01]), np.array([START, START]), np.zeros((2, 7)), np.zeros((2, 7))))
        yield sim


@pytest.mark.parametrize(("waypoint", "sentence"), [
    ([1000.0, -1.2, 1.0, 0.0, 0.0, 0.0, 0.0],
     (r"^waypoints: waypoint 1 at x, y, z = 1000, -1.2, 1 m is outside the greenhouse room \(x within ±6 m, y within ±5 m, "
      r"z from 0 to 3.5 m\)$")),
    ([0.0, -1.2, -0.5, 0.0, 0.0, 0.0, 0.0], r"^waypoints: waypoint 1 at x, y, z = 0, -1.2, -0.5 m is outside the greenhouse"),
    ([0.0, math.nan, 1.0, 0.0, 0.0, 0.0, 0.0], r"^waypoints: waypoint 1 is not finite \(x=0, y=nan, z=1, "),
    ([0.0, -1.2, 1.0, math.inf, 0.0, 0.0, 0.0], r"^waypoints: waypoint 1 is not finite \(.*yaw=inf"),
    ([0.0, -1.2, 1.0, 1e300, 0.0, 0.0, 0.0], r"^waypoints: waypoint 1 has yaw 1e\+300 rad, beyond ±10000 rad$"),
    ([0.0, -1.2, 1.0, 0.0, 0.0, 2.0, 0.0],
     r"^waypoints: waypoint 1 has q2 = 2 rad, outside the arm's joint limits \[-1.6, 1.6\] rad \(robot.arm.joint_limits\)$"),
], ids=["a-kilometre-away", "under-the-floor", "nan", "infinite-yaw", "huge-yaw", "joint-past-its-limit"])
def test_a_replan_through_a_waypoint_that_cannot_be_flown_is_refused_naming_it_before_planning(hovering: Simulation,
                                                                                               waypoint, sentence: str):
    good = START + [0.5, 0.0, 0.2, 0.0, 0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match=sentence):
        hovering.replan(np.array([good, waypoint]))


def test_waypoints_that_are_not_rows_of_seven_numbers_are_refused_in_one_line(hovering: Simulation):
    with pytest.raises(ValueError, match=r"^waypoints: shape \(3,\) is not rows of q\* \(x, y, z, yaw, q1, q2, q3\)$"):
        hovering.replan(np.zeros(3))
    with pytest.raises(ValueError, match=r"^waypoints: shape \(0, 7\) is not rows"):
        hovering.replan(np.zeros((0, 7)))
    with pytest.raises(ValueError, match=r"^waypoints: not an array of numbers \(list\)$"):
        hovering.replan([["a"] * 7])


@pytest.mark.parametrize(("hold", "sentence"), [
    (math.nan, "^Simulation: hold: Input should be a finite number$"),
    (1e9, "^Simulation: hold: Input should be less than or equal to 1000$"),
    (-1.0, "^Simulation: hold: Input should be greater than or equal to 0$"),
])
def test_a_simulation_refuses_a_hover_that_is_not_a_sane_number_of_seconds(demo_dir: Path, hold: float, sentence: str):
    with pytest.raises(ValueError, match=sentence):
        Simulation(load_config("demo"), demo_dir, hold=hold)


def test_a_simulation_validates_a_config_changed_without_validation(demo_dir: Path):
    config = load_config("demo")
    changed = config.model_copy(update={"controller": config.controller.model_copy(update={"rate_hz": math.nan})})
    with pytest.raises(ValueError, match="^Simulation config: controller.rate_hz: Input should be a finite number$"):
        Simulation(changed, demo_dir)
    with pytest.raises(ValueError, match="^Simulation: config is a dict, not a renderloop Config"):
        Simulation(config.model_dump(), demo_dir)


@pytest.mark.parametrize(("arguments", "sentence"), [
    ({"time_cost": math.nan}, "^PepperScanEnv: time_cost: Input should be a finite number$"),
    ({"time_cost": -1.0}, "^PepperScanEnv: time_cost: Input should be greater than or equal to 0$"),
    ({"max_views": 0}, "^PepperScanEnv: max_views: Input should be greater than or equal to 1$"),
    ({"max_views": 10**9}, "^PepperScanEnv: max_views: Input should be less than or equal to 1997$"),
    ({"max_flight_time": math.inf}, "^PepperScanEnv: max_flight_time: Input should be a finite number$"),
    ({"max_flight_time": 0.0}, "^PepperScanEnv: max_flight_time: Input should be greater than 0$"),
    ({"render_mode": "human"}, "^PepperScanEnv: render_mode: Input should be 'rgb_array'$"),
    ({"backend": "opengl"}, "^PepperScanEnv config: renderer.backend: Input should be 'cycles' or 'raster'$"),
])
def test_the_gym_environment_refuses_bad_arguments_before_it_makes_anything(monkeypatch, arguments: dict, sentence: str):
    from renderloop.loop import gym_env

    monkeypatch.setattr(gym_env.tempfile, "mkdtemp", lambda **_: pytest.fail("made a directory for refused arguments"))
    with pytest.raises(ValueError, match=sentence):
        gym_env.PepperScanEnv(**arguments)


def test_the_api_refuses_with_the_sentence_the_cli_prints(demo_dir: Path, monkeypatch, capsys, tmp_path: Path):
    """The same bound, the same words: controller.rate_hz out of range from a YAML file and from a changed Config."""
    (tmp_path / "fast.yaml").write_text("controller:\n  rate_hz: 5000\n", encoding="utf-8")
    code, _, err = cli(monkeypatch, capsys, "scene", "--config", str(tmp_path / "fast.yaml"), "--out", str(tmp_path / "out"))
    assert code == 2
    printed = err.strip().removeprefix(f"renderloop: error: {tmp_path / 'fast.yaml'}: ")
    config = load_config("demo")
    changed = config.model_copy(update={"controller": config.controller.model_copy(update={"rate_hz": 5000.0})})
    with pytest.raises(ValueError) as refused:
        Simulation(changed, demo_dir)
    assert str(refused.value) == f"Simulation config: {printed}"


@pytest.mark.parametrize("arguments", [
    ["run", "--config", "{tmp}/no\nsuch.yaml", "--out", "{tmp}/out"],  # a UserError naming the path
    ["scene", "--out", "{tmp}/a\nfile/run"],  # an OSError: a file where a directory must be
    ["render", "{tmp}/no\x1b[31mrun"],  # a terminal escape is a control character too
])
def test_a_cli_error_naming_a_path_with_a_newline_is_one_line(monkeypatch, capsys, tmp_path: Path, arguments: list[str]):
    (tmp_path / "a\nfile").write_text("not a directory", encoding="utf-8")
    code, _, err = cli(monkeypatch, capsys, *(argument.format(tmp=tmp_path) for argument in arguments))
    assert code in (1, 2)
    [line] = err.splitlines()
    assert line.startswith("renderloop: error: ") and line.isprintable()
    assert "\\n" in line or "\\x1b" in line  # the character is named, not dropped

