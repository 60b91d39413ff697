"""`renderloop plan DIR`: scan waypoints and the TOPP-RA trajectory, checked against the greenhouse."""

from __future__ import annotations

from pathlib import Path

import mujoco

from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.planning.scan import plan_scan
from renderloop.planning.waypoints import write_waypoints
from renderloop.rundir import files, names
from renderloop.rundir.stage import Job, Stage
from renderloop.scene.model import read_scene


def _plan(run_dir: Path, config: Config, job: Job) -> None:
    if config.mission.split == "rows":  # its missions are its rows' runs, which `renderloop run` makes
        raise UserError(f"{run_dir}: a compartment scanned a row a mission (mission.split: rows); `renderloop run` "
                        f"plans each row's mission in {names.ROW_RUNS}/row_<id>")
    model = mujoco.MjModel.from_xml_path(str(run_dir / names.WORLD))
    plan = plan_scan(read_scene(run_dir), config, model)
    write_waypoints(run_dir, plan.waypoints, plan.trajectory.waypoint_times)
    files.write_trajectory(run_dir, plan.trajectory.table())


STAGE = Stage("plan", needs=(names.CONFIG, names.SCENE, names.WORLD), work=_plan)
run_plan = STAGE.run
