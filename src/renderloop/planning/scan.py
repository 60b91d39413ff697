"""The scan of every plant, planned in memory: elliptical waypoints, the TOPP-RA trajectory through them, and the
check that it keeps clear of the greenhouse. `renderloop plan` writes what this returns; a `Simulation` flies it."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from renderloop.config import Config
from renderloop.planning.check import check_trajectory
from renderloop.planning.trajectory import Trajectory, time_parameterize
from renderloop.planning.waypoints import Waypoint, plan_waypoints
from renderloop.scene.model import Scene


@dataclass(frozen=True)
class ScanPlan:
    waypoints: list[Waypoint]
    trajectory: Trajectory  # passes waypoint i at trajectory.waypoint_times[i]


def plan_scan(scene: Scene, config: Config, model: mujoco.MjModel) -> ScanPlan:
    """The scan of `scene`, checked against `model` (the scene's MuJoCo world): a `Clash` where it would hit."""
    waypoints = plan_waypoints(scene, config)
    trajectory = time_parameterize(np.array([w.dofs for w in waypoints]), config.planner)
    check_trajectory(model, trajectory.t, trajectory.q, scene.room)
    return ScanPlan(waypoints, trajectory)
