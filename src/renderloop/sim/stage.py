"""`renderloop fly DIR`: fly the planned trajectory in MuJoCo; log the flight and the camera poses."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderloop.config import Config
from renderloop.planning.waypoints import read_waypoints
from renderloop.robot.kinematics import planned_camera_positions
from renderloop.rundir import files, names
from renderloop.rundir.stage import Job, Stage
from renderloop.scene.model import read_scene
from renderloop.sim.corridor import fly_in_corridor
from renderloop.sim.flight import FlightLog, Reference, camera_frames, flight_table
from renderloop.sim.plots import draw_flight_paths, draw_tracking_error


def write_flight(run_dir: Path, config: Config, log: FlightLog, frames: np.ndarray) -> None:
    """flight.csv, the camera poses at the `frames` ticks (groundtruth.txt) and the flight's figures."""
    scene, waypoints = read_scene(run_dir), read_waypoints(run_dir)
    planned_camera = planned_camera_positions(log.reference, config.robot.arm)
    files.write_flight(run_dir, flight_table(log, planned_camera))
    files.write_poses(run_dir, log.t[frames], log.camera_position[frames], log.camera_rotation[frames])
    draw_flight_paths(scene, waypoints, log, planned_camera, run_dir / names.FLIGHT_PATHS)
    draw_tracking_error(log, planned_camera, run_dir / names.TRACKING_ERROR)


def _fly(run_dir: Path, config: Config, job: Job) -> None:
    table = files.read_trajectory(run_dir)
    read_waypoints(run_dir)  # every input is read before any output is replaced
    reference = Reference(table[:, 0], table[:, 1:8], table[:, 8:15], table[:, 15:22])
    log = fly_in_corridor(run_dir / names.WORLD, config, reference)
    write_flight(run_dir, config, log, camera_frames(log, reference.t[-1], config.camera.rate_hz))


NEEDS = (names.CONFIG, names.SCENE, names.WORLD, names.WAYPOINTS, names.TRAJECTORY)
STAGE = Stage("fly", needs=NEEDS, work=_fly)
run_fly = STAGE.run
