"""Forward and inverse kinematics of the aerial manipulator, down to the camera optical frame.

T_w^cam = T_w^b · T_b^0 · T_0^ee (the paper's chain). The arm is a pitch chain: three
revolute joints about axes parallel to body y, the first at `mount` in the body frame;
with q = 0 every link points along body +x. Positive q pitches the next link down
(a right-handed rotation about +y takes x towards -z). The optical frame (REP-103:
x right, y down, z forward) sits at the tip with z along the last link.

The planned DoF q* = (x, y, z, yaw, q1, q2, q3) assume a level body (hover), so a
camera pose is reachable when it has no roll about its optical axis; two of the seven
DoF are redundant and the IK keeps q1, q2 at a chosen posture.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from renderloop.config import ArmConfig

# Columns: the optical x, y, z axes in the frame of the last link (x along the link, y left, z up).
OPTICAL_IN_LINK = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def rot_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def homogeneous(rotation: np.ndarray, translation: Sequence[float]) -> np.ndarray:
    transform = np.eye(4)
    transform[:3, :3] = rotation
    transform[:3, 3] = translation
    return transform


def yaw_quaternion_wxyz(yaw: float) -> np.ndarray:
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


def arm_frames(arm: ArmConfig, q: Sequence[float]) -> list[np.ndarray]:
    """Body-frame poses of joint 1, joint 2, joint 3 (each after its rotation) and the optical frame."""
    frames = []
    transform = homogeneous(np.eye(3), arm.mount)
    offsets = (0.0, *arm.link_lengths[:2])
    for angle, offset in zip(q, offsets):
        transform = transform @ homogeneous(np.eye(3), (offset, 0.0, 0.0)) @ homogeneous(rot_y(angle), (0, 0, 0))
        frames.append(transform)
    frames.append(transform @ homogeneous(OPTICAL_IN_LINK, (arm.link_lengths[2], 0.0, 0.0)))
    return frames


def body_to_camera(arm: ArmConfig, q: Sequence[float]) -> np.ndarray:
    """T_b^cam: the optical frame in the body frame for joint angles q."""
    return arm_frames(arm, q)[-1]


def camera_pose(body_position: Sequence[float], body_rotation: np.ndarray, arm: ArmConfig, q: Sequence[float]) -> np.ndarray:
    """T_w^cam for any body attitude (the simulated state, not only hover)."""
    return homogeneous(body_rotation, body_position) @ body_to_camera(arm, q)


def dofs_to_camera_pose(dofs: Sequence[float], arm: ArmConfig) -> np.ndarray:
    """T_w^cam for planned DoF q* = (x, y, z, yaw, q1, q2, q3), body level."""
    x, y, z, yaw, *q = dofs
    return camera_pose((x, y, z), rot_z(yaw), arm, q)


def camera_rotation(yaw: float, pitch: float) -> np.ndarray:
    """Optical frame orientation of a level camera; positive pitch looks down."""
    return rot_z(yaw) @ rot_y(pitch) @ OPTICAL_IN_LINK


def look_at(camera_position: Sequence[float], target: Sequence[float]) -> np.ndarray:
    """T_w^cam of a camera at `camera_position` looking at `target` with no roll."""
    direction = np.asarray(target, dtype=float) - np.asarray(camera_position, dtype=float)
    yaw = math.atan2(direction[1], direction[0])
    pitch = math.atan2(-direction[2], math.hypot(direction[0], direction[1]))
    return homogeneous(camera_rotation(yaw, pitch), camera_position)


class UnreachablePose(ValueError):
    """The wanted camera pose cannot be reached with a level body within the joint limits."""


def camera_pose_to_dofs(
    pose: np.ndarray, arm: ArmConfig, posture: Sequence[float] | None = None, roll_tolerance: float = 1e-6
) -> np.ndarray:
    """Inverse kinematics: the planned DoF that put the optical frame at `pose`.

    The optical z axis gives yaw and the total pitch q1 + q2 + q3; q1, q2 stay at
    `posture` (the config's nominal posture by default), q3 takes the rest, and the
    body position follows from the arm's reach.
    """
    forward = pose[:3, 2]
    yaw = math.atan2(forward[1], forward[0])
    pitch = math.atan2(-forward[2], math.hypot(forward[0], forward[1]))
    expected_x = -rot_z(yaw)[:, 1]
    roll_error = float(np.linalg.norm(pose[:3, 0] - expected_x))
    if math.hypot(forward[0], forward[1]) < 1e-9 or roll_error > roll_tolerance:
        raise UnreachablePose("camera pose has a roll about its optical axis (or looks straight up/down)")
    q1, q2 = arm.nominal_posture if posture is None else posture
    q = (q1, q2, pitch - q1 - q2)
    low, high = arm.joint_limits
    for index, angle in enumerate(q, start=1):
        if not low <= angle <= high:
            raise UnreachablePose(f"joint q{index} = {angle:.3f} rad is outside the limits [{low}, {high}]")
    reach = rot_z(yaw) @ body_to_camera(arm, q)[:3, 3]
    x, y, z = pose[:3, 3] - reach
    return np.array([x, y, z, yaw, *q])


def planned_camera_positions(dofs: np.ndarray, arm: ArmConfig) -> np.ndarray:
    """Camera positions for many q* at once (level body): the path the camera is meant to fly."""
    dofs = np.atleast_2d(dofs)
    angles = np.cumsum(dofs[:, 4:7], axis=1)
    lengths = np.asarray(arm.link_lengths)
    forward = arm.mount[0] + np.cos(angles) @ lengths
    up = arm.mount[2] - np.sin(angles) @ lengths
    yaw = dofs[:, 3]
    return np.column_stack([
        dofs[:, 0] + np.cos(yaw) * forward - np.sin(yaw) * arm.mount[1],
        dofs[:, 1] + np.sin(yaw) * forward + np.cos(yaw) * arm.mount[1],
        dofs[:, 2] + up,
    ])
