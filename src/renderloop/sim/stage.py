"""`renderloop fly DIR`: fly the planned trajectory in MuJoCo; log the flight and the camera poses."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from renderloop.config import Config
from renderloop.io import rundir
from renderloop.io.csvtable import read_csv, write_csv
from renderloop.io.tum import write_tum
from renderloop.planning.stage import read_waypoints
from renderloop.planning.trajectory import HEADER
from renderloop.robot.kinematics import planned_camera_positions
from renderloop.scene.model import load_scene
from renderloop.sim.flight import FlightLog, Reference, fly
from renderloop.sim.plots import draw_flight_paths, draw_tracking_error

INPUTS = ("config.yaml", "scene.json", "world.xml", "waypoints.csv", "trajectory.csv")
OUTPUTS = ("flight.csv", "groundtruth.txt", "flight_paths.png", "tracking_error.png")
FLIGHT_HEADER = [
    "t", "x", "y", "z", "qx", "qy", "qz", "qw", "q1", "q2", "q3", "w1", "w2", "w3", "w4",
    "ref_x", "ref_y", "ref_z", "ref_yaw", "ref_q1", "ref_q2", "ref_q3",
    "err_x", "err_y", "err_z", "err_yaw", "cam_x", "cam_y", "cam_z", "cam_err", "contacts", "saturated",
]
GROUNDTRUTH_COMMENT = (
    "renderloop ground truth: pose of the camera optical frame (x right, y down, z forward)\n"
    "in the world frame (ENU, z up), from the simulated arm; time in simulation seconds"
)


def flight_table(log: FlightLog, planned_camera: np.ndarray) -> np.ndarray:
    yaw = np.arctan2(2 * (log.quaternion[:, 3] * log.quaternion[:, 2] + log.quaternion[:, 0] * log.quaternion[:, 1]),
                     1 - 2 * (log.quaternion[:, 1] ** 2 + log.quaternion[:, 2] ** 2))
    errors = np.column_stack([log.reference[:, :3] - log.position, np.remainder(log.reference[:, 3] - yaw + np.pi, 2 * np.pi) - np.pi])
    camera_error = np.linalg.norm(log.camera_position - planned_camera, axis=1)
    return np.column_stack([
        log.t, log.position, log.quaternion, log.joints, log.rotor_speeds, log.reference,
        errors, log.camera_position, camera_error, log.contacts, log.saturated,
    ])


def camera_frames(log: FlightLog, duration: float, rate_hz: float) -> np.ndarray:
    """Indices of the log at the camera's instants k / rate_hz (the nearest control tick)."""
    times = np.arange(0.0, duration + 1e-9, 1.0 / rate_hz)
    return np.unique(np.clip(np.searchsorted(log.t, times - 1e-9), 0, len(log.t) - 1))


def run_fly(run_dir: Path, config: Config, force: bool = False) -> bool:
    run_dir = Path(run_dir)
    rundir.require(run_dir, INPUTS, "plan")
    if not force and rundir.complete(run_dir, OUTPUTS, INPUTS):
        return False
    table = read_csv(run_dir / "trajectory.csv", HEADER)
    waypoints = read_waypoints(run_dir / "waypoints.csv")  # every input is read before any output is replaced
    scene = load_scene(run_dir / "scene.json")
    reference = Reference(table[:, 0], table[:, 1:8], table[:, 8:15], table[:, 15:22])
    model = mujoco.MjModel.from_xml_path(str(run_dir / "world.xml"))
    log = fly(model, config, reference)
    planned_camera = planned_camera_positions(log.reference, config.robot.arm)
    frames = camera_frames(log, reference.t[-1], config.camera.rate_hz)

    write_csv(run_dir / "flight.csv", FLIGHT_HEADER, flight_table(log, planned_camera), fmt=["%.6f"] * 30 + ["%d", "%d"])
    write_tum(run_dir / "groundtruth.txt", log.t[frames], log.camera_position[frames], log.camera_rotation[frames], GROUNDTRUTH_COMMENT)
    draw_flight_paths(scene, waypoints, log, planned_camera, run_dir / "flight_paths.png")
    draw_tracking_error(log, planned_camera, run_dir / "tracking_error.png")
    return True
