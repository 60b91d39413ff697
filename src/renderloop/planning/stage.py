"""`renderloop plan DIR`: scan waypoints and the TOPP-RA trajectory, checked against the greenhouse."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from renderloop.config import Config
from renderloop.planning.check import check_trajectory
from renderloop.planning.trajectory import time_parameterize
from renderloop.planning.waypoints import plan_waypoints, write_waypoints
from renderloop.rundir import files, names
from renderloop.rundir.stage import Job, Stage
from renderloop.scene.model import read_scene


def _plan(run_dir: Path, config: Config, job: Job) -> None:
    scene = read_scene(run_dir)
    waypoints = plan_waypoints(scene, config)
    trajectory = time_parameterize(np.array([w.dofs for w in waypoints]), config.planner)
    model = mujoco.MjModel.from_xml_path(str(run_dir / names.WORLD))
    check_trajectory(model, trajectory.t, trajectory.q, scene.room)
    write_waypoints(run_dir, waypoints, trajectory.waypoint_times)
    files.write_trajectory(run_dir, trajectory.table())


STAGE = Stage("plan", needs=(names.CONFIG, names.SCENE, names.WORLD), work=_plan)
run_plan = STAGE.run
