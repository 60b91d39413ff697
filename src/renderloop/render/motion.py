"""Where the camera was while its shutter was open: the two poses motion blur is rendered between.

A frame taken at time t exposes from t - e/2 to t + e/2; the exposure time e is drawn per
frame from `camera.sensor.exposure_time`, from a generator of its own named stream (the
colour-sensor model's draws stay as they were). The poses at the shutter's opening and
closing come from the flown state, not from the plan: body position and joints are
interpolated linearly between the control ticks around each instant, the body attitude
by slerp, and `camera_pose` carries them to the optical frame.

The batch render reads that state from flight.csv; the online camera sees it tick by tick
and rounds each tick as flight.csv stores it (`stored`), and both interpolate between the
same two ticks (the last one before an instant and the first one at or after it), so the
two compute the same poses to the bit and render the same frames.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from renderloop.config import ArmConfig, SensorConfig
from renderloop.robot.kinematics import camera_pose

EXPOSURE_STREAM = 0xE7  # the frame's exposure time is drawn from SeedSequence([seed, EXPOSURE_STREAM, index])
STATE_COLUMNS = ("t", "x", "y", "z", "qx", "qy", "qz", "qw", "q1", "q2", "q3")  # of flight.csv, in this order


def stored(values: Sequence[float]) -> list[float]:
    """Values as flight.csv (rundir.files.FLIGHT_FORMAT, through io.csvtable.write_csv, which writes -0.0 as 0.0) and
    groundtruth.txt's timestamps give them back: six decimals."""
    return [float("%.6f" % (value + 0.0)) for value in values]


def exposure_time(settings: SensorConfig, seed: int, index: int) -> float:
    """Frame `index`'s exposure, s: its own stream, so a frame draws the same whichever worker or loop asks."""
    low, high = settings.exposure_time
    if high <= low:
        return float(low)
    return float(np.random.default_rng(np.random.SeedSequence([seed, EXPOSURE_STREAM, index])).uniform(low, high))


@dataclass(frozen=True)
class FlownStates:
    """The robot's state at the control ticks: t (N,), body position (N, 3), body quaternion qx qy qz qw (N, 4),
    joints q1..q3 (N, 3)."""

    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    joints: np.ndarray

    @classmethod
    def of_rows(cls, rows: np.ndarray | Sequence[Sequence[float]]) -> FlownStates:
        """From rows of `STATE_COLUMNS`."""
        table = np.asarray(rows, dtype=float).reshape(-1, len(STATE_COLUMNS))
        if len(table) == 0:
            raise ValueError("no flown state to interpolate")
        return cls(table[:, 0], table[:, 1:4], table[:, 4:8], table[:, 8:11])

    @classmethod
    def of_flight(cls, columns: dict[str, np.ndarray]) -> FlownStates:
        """From flight.csv's columns by name (`rundir.files.read_flight`)."""
        return cls.of_rows(np.column_stack([columns[name] for name in STATE_COLUMNS]))

    def at(self, time: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Body position, body rotation (3, 3) and joints at `time`; before the first tick or after the last the
        robot holds that tick's state (the flight starts at rest, and ends hovering)."""
        after = int(np.searchsorted(self.t, time, side="left"))  # the first tick at or after `time`
        if after == 0 or after == len(self.t):
            last = min(after, len(self.t) - 1)
            return self.position[last].copy(), _rotation(self.quaternion[last]), self.joints[last].copy()
        before = after - 1
        w = (time - self.t[before]) / (self.t[after] - self.t[before])
        position = self.position[before] + w * (self.position[after] - self.position[before])
        joints = self.joints[before] + w * (self.joints[after] - self.joints[before])
        return position, _rotation(slerp(self.quaternion[before], self.quaternion[after], w)), joints


def slerp(q0: np.ndarray, q1: np.ndarray, w: float) -> np.ndarray:
    """Spherical interpolation of unit quaternions (either order of components), the short way round."""
    q0, q1 = q0 / math.sqrt(_dot(q0, q0)), q1 / math.sqrt(_dot(q1, q1))
    dot = _dot(q0, q1)
    if dot < 0:  # q and -q are one rotation: go the short way
        q1, dot = -q1, -dot
    angle = np.arccos(min(dot, 1.0))
    if angle < 1e-9:
        blended = q0 + w * (q1 - q0)
        return blended / math.sqrt(_dot(blended, blended))
    return (np.sin((1 - w) * angle) * q0 + np.sin(w * angle) * q1) / np.sin(angle)


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """a . b summed in one fixed order: BLAS's dot (and so np.linalg.norm) rounds differently with the vectors'
    alignment in memory, and the online camera's states are a slice of the ticks flown so far, not flight.csv's table."""
    return float(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3])


def _rotation(quaternion_xyzw: np.ndarray) -> np.ndarray:
    return Rotation.from_quat(quaternion_xyzw).as_matrix()


def _camera_at(states: FlownStates, arm: ArmConfig, time: float) -> np.ndarray:
    position, rotation, joints = states.at(time)
    return camera_pose(position, rotation, arm, joints)


def exposure_poses(states: FlownStates, arm: ArmConfig, t: float, pose: np.ndarray, exposure: float) -> np.ndarray:
    """T_world_optical at the shutter's opening and closing (2, 4, 4) for the frame at `t` seen from `pose`.

    The flown motion is applied relative to `pose` (the frame's groundtruth pose, MuJoCo's camera site): the
    kinematic chain and the site agree only to rounding, and anchoring keeps the blurred frame centred on the ideal
    frame it is compared with (at rest both poses are `pose` itself)."""
    to_centre = np.linalg.inv(_camera_at(states, arm, t))
    return np.stack([pose @ to_centre @ _camera_at(states, arm, t + side * exposure / 2) for side in (-1.0, 1.0)])


def frames_motion(states: FlownStates, arm: ArmConfig, times: np.ndarray, poses: np.ndarray, settings: SensorConfig,
                  seed: int) -> np.ndarray:
    """The shutter's two poses of every frame (N, 2, 4, 4), for the batch render."""
    motion = [exposure_poses(states, arm, float(t), pose, exposure_time(settings, seed, index))
              for index, (t, pose) in enumerate(zip(times, poses))]
    return np.array(motion).reshape(len(poses), 2, 4, 4)
