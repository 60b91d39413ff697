"""The Gymnasium environment renderloop/PepperScan-v0: it follows Gymnasium's API, is deterministic for a seed, never
refuses an action (it flies the nearest reachable view), and rewards the fruit newly confirmed on its plant."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import renderloop  # noqa: F401  (registers the environment)
from renderloop.config import Config, load_config
from renderloop.loop.gym_env import ENV_ID, PepperScanEnv
from renderloop.loop.viewpoints import action_to_view
from renderloop.robot.kinematics import dofs_to_camera_pose

SEED = 3


@pytest.fixture(scope="module")
def small() -> Config:
    """The demo greenhouse seen by a 160 x 120 camera: frames, detection and counting stay quick."""
    return load_config("demo").override({"camera": {"width": 160, "height": 120}})


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> Path:
    """One directory for the scenes of every environment here: a scene seed another test used resets fast."""
    return tmp_path_factory.mktemp("gym")


def opposite(view: np.ndarray) -> float:
    """The azimuth action that asks for the far side of the plant from `view`."""
    return math.remainder(view[0] + math.pi, 2 * math.pi) / math.pi


@pytest.mark.filterwarnings("ignore:.*maximum value is infinity")  # the counter's counts and seconds have no bound
def test_the_environment_passes_gymnasiums_checker(small: Config, scenes: Path):
    env = gymnasium.make(ENV_ID, config=small, max_views=2, render_mode="rgb_array", run_dir=scenes)
    try:
        check_env(env.unwrapped)
        frame = env.unwrapped.render()  # the last frame check_env's episodes took
        assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    finally:
        env.close()


def test_gymnasium_makes_the_environment_once_renderloop_is_imported():
    script = """
import sys
import gymnasium
import renderloop
assert "renderloop.loop.gym_env" not in sys.modules and "mujoco" not in sys.modules  # registered, not imported
env = gymnasium.make("renderloop/PepperScan-v0")
assert type(env.unwrapped).__name__ == "PepperScanEnv"
assert env.observation_space["rgb"].shape == (240, 320, 3)  # the demo preset's camera
scenes = env.unwrapped.run_dir  # the temporary directory the environment owns
assert scenes.is_dir()
env.close()
env.close()  # closing twice is harmless
assert not scenes.exists()
renderloop._register_environments()  # a second registration is harmless
"""
    subprocess.run([sys.executable, "-c", script], check=True, timeout=120)


def test_the_same_seed_gives_the_same_episode(small: Config, scenes: Path):
    actions = [np.array([0.3, 0.5, -0.5], np.float32), np.array([-0.2, -1.0, 1.0], np.float32)]
    runs = []
    for _ in range(2):
        with PepperScanEnv(small, max_views=2, run_dir=scenes) as env:
            observation, info = env.reset(seed=SEED)
            run = [(observation, info)]
            for action in actions:
                run.append(env.step(action))
            runs.append(run)
    assert gymnasium.utils.env_checker.data_equivalence(runs[0], runs[1], exact=True)


def test_an_action_out_of_reach_is_flown_to_the_nearest_reachable_view(small: Config, scenes: Path):
    with PepperScanEnv(small, max_views=2, run_dir=scenes) as env:
        _, info = env.reset(seed=SEED, options={"plant": 1})  # a plant with neighbours on both sides in its row
        with pytest.raises(ValueError, match=r"^PepperScanEnv.step: action \(2,\) is not 3 numbers"):
            env.step(np.zeros(2, np.float32))  # no action at all: refused before anything flies
        assert env.sim.t == 0.0 and env.views == 0
        # the far side of the plant, through its row, and far outside the action's ranges
        action = np.array([opposite(info["view"]), 7.0, -3.0], np.float32)
        observation, _, _, _, info = env.step(action)
        wanted = action_to_view(action, env.plant)
        assert wanted.height == pytest.approx(0.3) and wanted.distance == pytest.approx(0.35)  # clipped
        assert info["projected"] and not np.allclose(info["view"], info["requested_view"])
        assert np.allclose(info["view"][1:], info["requested_view"][1:])  # the same ring, another azimuth
        planned = dofs_to_camera_pose(info["dofs"], small.robot.arm)[:3, 3]
        assert np.linalg.norm(observation["camera_pose"][:3] - planned) < 0.03
        assert env.sim.log().contacts.sum() == 0


def test_the_reward_is_the_fruit_newly_confirmed_less_the_flight_time(small: Config, scenes: Path):
    with PepperScanEnv(small, max_views=3, time_cost=0.1, run_dir=scenes) as env:
        observation, info = env.reset(seed=SEED, options={"plant": 3})  # the end of its row: round it to the far side
        confirmed, rewards, far = observation["counter"][0], [], opposite(info["view"])
        for action in ([0.5, 0.0, 0.0], [far, 0.0, 0.0], [far, 0.5, -0.5]):  # +y (past the row's end), the far side
            observation, reward, terminated, _, info = env.step(np.array(action, np.float32))
            gained = observation["counter"][0] - confirmed
            assert reward == pytest.approx(gained - 0.1 * info["flight_time"], abs=1e-6)
            assert info["confirmed"] == observation["counter"][0] and info["flight_time"] > 0
            confirmed, rewards = observation["counter"][0], [*rewards, gained]
        assert terminated and observation["counter"][2] == 4  # the start view and three more
        assert sum(rewards) > 0  # fruit were confirmed
        assert observation["counter"][3] == pytest.approx(env.sim.t, abs=1e-4)  # the flight since the reset
