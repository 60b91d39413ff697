"""`renderloop plan DIR`: scan waypoints and the TOPP-RA trajectory, checked against the greenhouse."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from renderloop.config import Config
from renderloop.io import rundir
from renderloop.errors import UserError
from renderloop.io.atomic import write_text
from renderloop.io.csvtable import write_csv
from renderloop.planning.check import check_trajectory
from renderloop.planning.trajectory import HEADER, time_parameterize
from renderloop.planning.waypoints import Waypoint, plan_waypoints
from renderloop.scene.model import load_scene

INPUTS = ("config.yaml", "scene.json", "world.xml")
OUTPUTS = ("waypoints.csv", "trajectory.csv")
WAYPOINT_HEADER = ["index", "kind", "plant", "side", "t", "x", "y", "z", "yaw", "q1", "q2", "q3"]
KINDS = ("start", "scan", "transit", "end")


def run_plan(run_dir: Path, config: Config, force: bool = False) -> bool:
    run_dir = Path(run_dir)
    rundir.require(run_dir, INPUTS, "scene")
    if not force and rundir.complete(run_dir, OUTPUTS, INPUTS):
        return False
    scene = load_scene(run_dir / "scene.json")
    waypoints = plan_waypoints(scene, config)
    trajectory = time_parameterize(np.array([w.dofs for w in waypoints]), config.planner)
    model = mujoco.MjModel.from_xml_path(str(run_dir / "world.xml"))
    check_trajectory(model, trajectory.t, trajectory.q, scene.room)

    write_waypoints(run_dir / "waypoints.csv", waypoints, trajectory.waypoint_times)
    write_csv(run_dir / "trajectory.csv", HEADER, trajectory.table())
    return True


def write_waypoints(path: Path, waypoints: list[Waypoint], times: np.ndarray) -> None:
    """One row per waypoint: what it is for (kind, plant, side), when it is passed, and q* (yaw unwrapped)."""
    dofs = np.array([w.dofs for w in waypoints])
    dofs[:, 3] = np.unwrap(dofs[:, 3])
    lines = [",".join(WAYPOINT_HEADER)]
    for index, (waypoint, time, q) in enumerate(zip(waypoints, times, dofs)):
        numbers = ",".join(f"{value:.6f}" for value in (time, *q))
        lines.append(f"{index},{waypoint.kind},{waypoint.plant},{waypoint.side},{numbers}")
    write_text(path, "\n".join(lines) + "\n")


def read_waypoints(path: Path) -> list[Waypoint]:
    """The waypoints of `waypoints.csv`, each with the time it is passed as `time`."""
    path = Path(path)
    try:
        rows = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise UserError(f"{path}: no such file (run `renderloop plan` first)") from None
    if not rows or rows[0] != ",".join(WAYPOINT_HEADER):
        raise UserError(f"{path}: header is not {','.join(WAYPOINT_HEADER)}")
    waypoints = []
    for number, row in enumerate(rows[1:], start=2):
        fields = row.split(",")
        try:
            if len(fields) != len(WAYPOINT_HEADER) or fields[1] not in KINDS:
                raise ValueError
            values = np.array([float(v) for v in fields[4:]])
            waypoints.append(Waypoint(fields[1], values[1:], int(fields[2]), fields[3], float(values[0])))
        except ValueError:
            raise UserError(f"{path}: line {number} is not a waypoint row") from None
    return waypoints
