"""Time-optimal parameterisation of the waypoint path with TOPP-RA (the `toppra` package).

The path is a cubic spline through the waypoints over a chord-length parameter;
TOPP-RA finds the fastest traversal within per-DoF velocity and acceleration limits,
and ParametrizeConstAccel turns it into a trajectory that keeps them (the spline
parametrizer can overshoot). Yaw is unwrapped first so that a turn across ±π is a
small turn, not a 2π spin. TOPP-RA's limits are the configured ones times
`limit_margin`: sampled at 100 Hz, constant-acceleration segments can overshoot a
limit slightly (docs/stages/plan.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderloop.config import PlannerConfig
from renderloop.errors import UserError

ANGLE_WEIGHT = 0.3  # m per rad in the path parameter, so a pure turn still advances it
GRID_STEP = 0.02  # path-parameter spacing of TOPP-RA's gridpoints at most


@dataclass(frozen=True)
class Trajectory:
    t: np.ndarray  # (N,)
    q: np.ndarray  # (N, 7)
    qd: np.ndarray  # (N, 7)
    qdd: np.ndarray  # (N, 7)
    waypoint_times: np.ndarray  # (M,) when the trajectory passes each waypoint

    def table(self) -> np.ndarray:
        return np.column_stack([self.t, self.q, self.qd, self.qdd])


def path_norm(steps: np.ndarray) -> np.ndarray:
    """The path parameter's length of q* steps (or speed of q̇*): metres plus weighted radians."""
    steps = np.asarray(steps, dtype=float)
    return np.linalg.norm(steps[..., :3], axis=-1) + ANGLE_WEIGHT * np.linalg.norm(steps[..., 3:], axis=-1)


def path_parameter(dofs: np.ndarray) -> np.ndarray:
    """Chord length over positions plus weighted angles; refuses waypoints that coincide."""
    lengths = path_norm(np.diff(dofs, axis=0))
    for index in np.flatnonzero(lengths < 1e-6):
        raise UserError(f"planner: waypoints {index} and {index + 1} coincide; a path cannot pass a point twice in a row")
    return np.concatenate([[0.0], np.cumsum(lengths)])


def _gridpoints(ss: np.ndarray) -> np.ndarray:
    """Every waypoint plus even subdivisions, so the limits hold between waypoints too."""
    pieces = np.maximum(2, np.ceil(np.diff(ss) / GRID_STEP).astype(int))
    return np.concatenate([np.linspace(a, b, n, endpoint=False) for a, b, n in zip(ss[:-1], ss[1:], pieces)] + [ss[-1:]])


def _times_at(gridpoints: np.ndarray, path_velocity: np.ndarray) -> np.ndarray:
    """Time at each gridpoint of a constant-acceleration parameterisation (ds / mean path velocity)."""
    mean = (path_velocity[:-1] + path_velocity[1:]) / 2
    return np.concatenate([[0.0], np.cumsum(np.diff(gridpoints) / np.maximum(mean, 1e-12))])


def time_parameterize(waypoints: np.ndarray, planner: PlannerConfig, start_velocity: np.ndarray | None = None) -> Trajectory:
    """The fastest trajectory through `waypoints` within the limits, from rest or, for a replan mid-flight, leaving
    the first waypoint with `start_velocity` (q̇*: the path starts along it at its speed); it always ends at rest."""
    # Imported here: toppra imports matplotlib.pyplot, slow to import, which commands that only read a trajectory never need.
    import toppra
    import toppra.algorithm
    import toppra.constraint

    dofs = np.array(waypoints, dtype=float)
    dofs[:, 3] = np.unwrap(dofs[:, 3])
    ss = path_parameter(dofs)
    start_speed = 0.0
    if start_velocity is None:
        path = toppra.SplineInterpolator(ss, dofs, bc_type="clamped")
    else:
        start_speed = float(path_norm(start_velocity))
        tangent = np.asarray(start_velocity, dtype=float) / start_speed  # dq*/ds: unit speed in the path parameter
        path = toppra.SplineInterpolator(ss, dofs, bc_type=((1, tangent), (1, np.zeros(dofs.shape[1]))))
    velocity = planner.limit_margin * np.asarray(planner.velocity_limits)
    acceleration = planner.limit_margin * np.asarray(planner.acceleration_limits)
    constraints = [
        toppra.constraint.JointVelocityConstraint(np.column_stack([-velocity, velocity])),
        toppra.constraint.JointAccelerationConstraint(np.column_stack([-acceleration, acceleration])),
    ]
    gridpoints = _gridpoints(ss)
    instance = toppra.algorithm.TOPPRA(constraints, path, gridpoints=gridpoints, parametrizer="ParametrizeConstAccel")
    trajectory = instance.compute_trajectory(start_speed, 0.0)
    if trajectory is None:
        raise UserError("planner: TOPP-RA found no feasible parameterisation (check the limits and the waypoints)")
    data = instance.problem_data
    grid_times = _times_at(np.asarray(data.gridpoints), np.asarray(data.sd_vec))
    waypoint_times = np.interp(ss, np.asarray(data.gridpoints), grid_times)

    duration = float(trajectory.duration)
    count = math.ceil(duration * planner.sample_rate_hz) + 1
    times = np.arange(count) / planner.sample_rate_hz
    clamped = np.minimum(times, duration)
    q, qd, qdd = (np.asarray(trajectory(clamped, order)) for order in (0, 1, 2))
    at_rest = times >= duration
    qd[at_rest] = 0.0
    qdd[at_rest] = 0.0
    return Trajectory(t=times, q=q, qd=qd, qdd=qdd, waypoint_times=waypoint_times)
