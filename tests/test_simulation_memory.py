"""A Simulation built in memory (no run directory) writes nothing, and flies and sees what the one built from a run
directory's files does: the same scene, the same plan, the same flight, the same camera poses and frames."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from renderloop.config import load_config
from renderloop.loop.simulation import Simulation
from renderloop.planning.waypoints import read_waypoints
from renderloop.rundir import files
from renderloop.scene.model import read_scene

CONFIG = load_config("demo").override({"renderer": {"backend": "raster"}, "camera": {"width": 160, "height": 120}})


def _flown(sim: Simulation, until: float) -> tuple:
    sim.follow(sim.scan_trajectory())
    camera = sim.add_camera(rate_hz=1.0)
    sim.run_until(until)
    frames = camera.frames_until(sim.t)
    return sim.log(), [(frame.timestamp, frame.pose, frame.files) for frame in frames]


@pytest.fixture(scope="module")
def on_disk(tmp_path_factory) -> tuple[Path, tuple]:
    run_dir = tmp_path_factory.mktemp("disk") / "run"
    with Simulation(CONFIG, run_dir) as sim:
        flown = _flown(sim, 4.0)
    return run_dir, flown


def test_a_simulation_without_a_run_directory_writes_nothing_and_sees_what_one_with_files_sees(
        on_disk, tmp_path: Path, monkeypatch):
    run_dir, (disk_log, disk_frames) = on_disk
    here = tmp_path / "cwd"
    here.mkdir()
    monkeypatch.chdir(here)
    with Simulation(CONFIG) as sim:
        assert sim.run_dir is None and sim.scene == read_scene(run_dir)
        log, frames = _flown(sim, 4.0)
    assert not os.listdir(here)
    for field in ("t", "position", "quaternion", "joints", "rotor_speeds", "reference", "camera_position"):
        assert np.array_equal(getattr(log, field), getattr(disk_log, field)), field
    assert len(frames) == len(disk_frames) == 4
    for (t, pose, images), (disk_t, disk_pose, disk_images) in zip(frames, disk_frames):
        assert t == disk_t and np.array_equal(pose, disk_pose) and images == disk_images


def test_the_plan_in_memory_is_the_plan_the_run_directory_holds(on_disk):
    """`fly` flies trajectory.csv: the plan in memory is the same numbers, to the bit (tests/test_loop.py flies a
    Simulation against `fly`)."""
    run_dir, _ = on_disk
    with Simulation(CONFIG) as sim:
        memory = sim.scan_trajectory()
    assert np.array_equal(np.column_stack([memory.t, memory.q, memory.qd, memory.qdd]), files.read_trajectory(run_dir))
    assert np.array_equal(memory.waypoint_times, [w.time for w in read_waypoints(run_dir)])
