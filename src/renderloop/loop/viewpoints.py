"""Viewpoints around one plant and which of them the robot can fly to from where it is.

A view is (azimuth, height, distance) about the plant's axis, the camera looking at the middle
of its canopy with no roll (on a canopy taller than the camera sees whole, at the plant's axis
near its own height: `aim_point`); `Projector.project` turns any wanted view into the reachable view
nearest to it and the waypoints that fly there round the plant (the rule is described in
`renderloop.loop.gym_env`, the environment that exposes it as an action space).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.planning.check import check_trajectory
from renderloop.planning.trajectory import path_norm
from renderloop.planning.waypoints import scan_target
from renderloop.robot.kinematics import UnreachablePose, camera_pose_to_dofs, look_at
from renderloop.scene.model import Plant, Scene

HEIGHT_RANGE = 0.3  # m above or below the canopy's middle; a tall canopy's views reach up and down it (height_range)
CANOPY_MARGIN = 0.2  # m: a tall canopy's highest and lowest views stand this far inside its ends
DISTANCE_RANGE = (0.35, 0.75)  # m, camera to the plant's axis, horizontally
WAYPOINT_STEP = math.radians(10.0)  # largest azimuth between the waypoints of a flight around the plant
SEARCH_STEP = math.radians(5.0)  # azimuth step of the search for the nearest reachable view
RING_BLENDS = (1.0, 0.75, 0.5, 0.25, 0.0)  # rings searched: the requested one, then towards the current view's
CHECK_STEP = 0.02  # path length (m, plus 0.3 m per rad) between checked q* samples
SAME_VIEW = 1e-3  # m: a view nearer than this to the current one is the current one


@dataclass(frozen=True)
class View:
    azimuth: float  # rad, counter-clockwise from world +x, in (-π, π]
    height: float  # m above the canopy's middle
    distance: float  # m, camera to the plant's axis, horizontally

    def array(self) -> np.ndarray:
        return np.array([self.azimuth, self.height, self.distance])


def wrap(angle: float) -> float:
    """An angle in (-π, π]."""
    wrapped = math.remainder(angle, 2 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def height_range(plant: Plant) -> float:
    """How far above or below the canopy's middle a view may be, m: HEIGHT_RANGE, or for a canopy taller than the
    camera sees whole, up to CANOPY_MARGIN inside its ends."""
    height = plant.bounds.max[2] - plant.position[2] - plant.pot.height
    return max(HEIGHT_RANGE, height / 2 - CANOPY_MARGIN)


def aim_point(plant: Plant, position: np.ndarray) -> np.ndarray:
    """What a camera at `position` looks at: the canopy's middle, or on a tall canopy the point of the plant's axis
    nearest its own height within HEIGHT_RANGE of a view's reach (so it looks as steeply as at a short canopy)."""
    middle = scan_target(plant)
    slack = height_range(plant) - HEIGHT_RANGE
    return middle + np.array([0.0, 0.0, float(np.clip(position[2] - middle[2], -slack, slack))])


def action_to_view(action: np.ndarray, plant: Plant) -> View:
    """The view of `plant` an action asks for, clipped to the ranges (NaN reads as 0)."""
    a = np.clip(np.nan_to_num(np.asarray(action, dtype=np.float64).reshape(3), nan=0.0), -1.0, 1.0)
    low, high = DISTANCE_RANGE
    return View(wrap(math.pi * a[0]), height_range(plant) * a[1], (low + high) / 2 + (high - low) / 2 * a[2])


def camera_position(plant: Plant, view: View) -> np.ndarray:
    direction = np.array([math.cos(view.azimuth), math.sin(view.azimuth), 0.0])
    return scan_target(plant) + view.distance * direction + np.array([0.0, 0.0, view.height])


def view_at(plant: Plant, position: np.ndarray) -> View:
    """The view whose camera sits at `position` (world): `camera_position` inverted, whatever the camera looks at."""
    offset = np.asarray(position, dtype=float) - scan_target(plant)
    return View(wrap(math.atan2(offset[1], offset[0])), float(offset[2]), math.hypot(offset[0], offset[1]))


class Projector:
    """Which views of one plant the robot can fly to from where it is: the projection rule of the module docstring."""

    def __init__(self, config: Config, scene: Scene, plant: Plant, world: Path) -> None:
        self.arm, self.plant, self.room = config.robot.arm, plant, tuple(scene.room)
        self.model = mujoco.MjModel.from_xml_path(str(world))  # its own copy: the check sets clearance margins on it

    def dofs(self, view: View) -> np.ndarray | None:
        """q* that put the camera at the view looking at its aim point; None when the arm cannot."""
        position = camera_position(self.plant, view)
        try:
            return camera_pose_to_dofs(look_at(position, aim_point(self.plant, position)), self.arm)
        except UnreachablePose:
            return None

    def clear(self, dofs: np.ndarray) -> bool:
        """Every q* (rows) free of the greenhouse, with the planner's clearance, and inside the room."""
        try:
            check_trajectory(self.model, np.arange(len(dofs)) * 0.1, np.asarray(dofs), self.room)
        except UserError:
            return False
        return True

    def path(self, start: View | None, end: View) -> list[np.ndarray] | None:
        """The waypoints (q*, the start's excluded) that fly from `start` round the plant to `end`, or None when
        the end cannot be reached or the way there is not clear. No start: the end alone (the start view)."""
        target = self.dofs(end)
        if target is None or not self.clear(target[None]):  # the cheap test first
            return None
        if start is None:
            return [target]
        turn = wrap(end.azimuth - start.azimuth)
        pieces = max(1, math.ceil(abs(turn) / WAYPOINT_STEP - 1e-9))
        views = [View(wrap(start.azimuth + turn * f), start.height + (end.height - start.height) * f,
                      start.distance + (end.distance - start.distance) * f) for f in np.linspace(0.0, 1.0, pieces + 1)]
        dofs = [self.dofs(view) for view in views]
        if any(q is None for q in dofs):
            return None
        samples = [dofs[0][None]]
        for a, b in zip(dofs[:-1], dofs[1:]):
            b = b.copy()
            b[3] = a[3] + wrap(b[3] - a[3])  # yaw the short way, as the planner unwraps it
            count = max(1, math.ceil(float(path_norm(b - a)) / CHECK_STEP))
            samples.append(a + np.outer(np.linspace(0.0, 1.0, count + 1)[1:], b - a))
        if not self.clear(np.vstack(samples)):
            return None
        return dofs[1:]

    def project(self, current: View | None, wanted: View) -> tuple[View, list[np.ndarray]]:
        """The reachable view nearest to `wanted` and the waypoints that fly there (empty: stay where it is)."""
        reference = current if current is not None else wanted
        for blend in RING_BLENDS if current is not None else (1.0,):
            height = reference.height + (wanted.height - reference.height) * blend
            distance = reference.distance + (wanted.distance - reference.distance) * blend
            for azimuth in self._azimuths(wanted.azimuth, reference.azimuth):
                view = View(azimuth, height, distance)
                if current is not None and self.same(view, current):
                    return current, []
                waypoints = self.path(current, view)
                if waypoints is not None:
                    return view, waypoints
        if current is None:
            raise UserError(f"plant {self.plant.id}: no view of it within the ranges is reachable")
        return current, []  # not reached: the current view lies on the last ring searched

    @staticmethod
    def _azimuths(wanted: float, current: float) -> list[float]:
        """Azimuths on a ring, nearest to `wanted` first; at equal distance, nearest to `current` first."""
        steps = round(math.pi / SEARCH_STEP)
        candidates = [wrap(wanted + k * SEARCH_STEP) for k in range(-steps + 1, steps + 1)]
        candidates.append(current)  # the current view's ring holds the current view
        return sorted(candidates, key=lambda a: (round(abs(wrap(a - wanted)), 9), round(abs(wrap(a - current)), 9), a))

    @staticmethod
    def same(a: View, b: View) -> bool:
        """Views within SAME_VIEW of each other (the camera less than that apart): the robot stays where it is."""
        return (abs(wrap(a.azimuth - b.azimuth)) * max(a.distance, b.distance) < SAME_VIEW
                and abs(a.height - b.height) < SAME_VIEW and abs(a.distance - b.distance) < SAME_VIEW)
