"""Check a planned trajectory against the greenhouse before anyone flies it.

The robot is posed kinematically (level body, the planned yaw and joints) along the
trajectory in the MuJoCo world, with a clearance margin on its geoms, and every
contact with the greenhouse is a planning error: the flight would hit it too.
"""

from __future__ import annotations

import mujoco
import numpy as np

from renderloop.errors import UserError
from renderloop.robot.kinematics import yaw_quaternion_wxyz
from renderloop.robot.mjcf import JOINT_NAMES, ROBOT_BODY

CLEARANCE = 0.03  # m
CHECK_PERIOD = 0.1  # s between checked samples


class Clash(UserError):
    """A trajectory that would leave the greenhouse or come within CLEARANCE of it, first at `t` (s); `waypoint`,
    where the caller knows it: the index of the first waypoint the trajectory passes at or after `t`."""

    def __init__(self, message: str, t: float, waypoint: int | None = None) -> None:
        super().__init__(message)
        self.t, self.waypoint = t, waypoint


def check_trajectory(model: mujoco.MjModel, t: np.ndarray, q: np.ndarray, room: tuple[float, float, float]) -> None:
    length, width, height = room
    outside = (np.abs(q[:, 0]) > length / 2) | (np.abs(q[:, 1]) > width / 2) | (q[:, 2] < 0.0) | (q[:, 2] > height)
    if outside.any():
        k = int(np.argmax(outside))
        raise Clash(f"planner: the trajectory leaves the greenhouse at t={t[k]:.2f} s, position {np.round(q[k, :3], 2).tolist()}",
                    float(t[k]))
    data = mujoco.MjData(model)
    uav = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, ROBOT_BODY)
    robot_geom = model.geom_bodyid >= uav
    saved_margin = model.geom_margin.copy()
    model.geom_margin[robot_geom] = CLEARANCE
    joints = [model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in JOINT_NAMES]
    try:
        step = max(1, int(round(CHECK_PERIOD / max(t[1] - t[0], 1e-9)))) if len(t) > 1 else 1
        for k in range(0, len(t), step):
            data.qpos[:3] = q[k, :3]
            data.qpos[3:7] = yaw_quaternion_wxyz(q[k, 3])
            data.qpos[joints] = q[k, 4:7]
            mujoco.mj_kinematics(model, data)
            mujoco.mj_collision(model, data)
            geoms = data.contact.geom[: data.ncon]
            hits = robot_geom[geoms[:, 0]] != robot_geom[geoms[:, 1]]
            if hits.any():
                a, b = geoms[int(np.argmax(hits))]
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, b if robot_geom[a] else a)
                raise Clash(f"planner: the trajectory comes within {CLEARANCE * 100:.0f} cm of {name} at t={t[k]:.2f} s", float(t[k]))
    finally:
        model.geom_margin[:] = saved_margin
