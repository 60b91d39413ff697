"""The closed loop in MuJoCo: cascade PID on the UAV, joint PIDs on the arm, rotors through the rotor model.

Each control tick (100 Hz by default) reads the state at its instant (the pose the
controller reads, the camera pose logged and the model terms used for compensation
all belong to it), then steps the physics several 2 ms steps with the controls held
(a zero-order hold, as on a flight controller). The state is MuJoCo's split step:
mj_step1 (positions, velocities, collisions) ends a tick, and the next tick's
controls enter before its mj_step2 (actuation, acceleration, integration), so no
part of a step is computed twice.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from renderloop.config import Config
from renderloop.control.arm import ArmController
from renderloop.control.uav import UavController
from renderloop.errors import UserError
from renderloop.robot.kinematics import yaw_quaternion_wxyz
from renderloop.robot.mjcf import CAMERA_SITE, JOINT_NAMES, ROBOT_BODY
from renderloop.robot.rotors import RotorModel

XYZW = [4, 5, 6, 3]  # the free joint's quaternion in qpos, reordered to qx qy qz qw


@dataclass(frozen=True)
class Reference:
    """Planned DoF q* over time, with derivatives: the trajectory as the controller samples it."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


@dataclass(frozen=True)
class Snapshot:
    """The robot at one control tick, before that tick's controls act."""

    position: np.ndarray  # body, world
    quaternion: np.ndarray  # body, qx qy qz qw
    joints: np.ndarray
    camera_position: np.ndarray  # optical frame, world
    camera_rotation: np.ndarray  # (3, 3) optical frame to world
    contacts: int  # robot-world contacts


@dataclass
class FlightLog:
    t: np.ndarray
    position: np.ndarray  # body, world
    quaternion: np.ndarray  # body, qx qy qz qw
    joints: np.ndarray
    rotor_speeds: np.ndarray
    reference: np.ndarray  # (N, 7)
    camera_position: np.ndarray
    camera_rotation: np.ndarray  # (N, 3, 3)
    contacts: np.ndarray
    saturated: np.ndarray


def camera_frames(log: FlightLog, duration: float, rate_hz: float) -> np.ndarray:
    """Indices of the log at the camera's instants k / rate_hz (the nearest control tick)."""
    times = np.arange(0.0, duration + 1e-9, 1.0 / rate_hz)
    return np.unique(np.clip(np.searchsorted(log.t, times - 1e-9), 0, len(log.t) - 1))


def flight_table(log: FlightLog, planned_camera: np.ndarray) -> np.ndarray:
    yaw = np.arctan2(2 * (log.quaternion[:, 3] * log.quaternion[:, 2] + log.quaternion[:, 0] * log.quaternion[:, 1]),
                     1 - 2 * (log.quaternion[:, 1] ** 2 + log.quaternion[:, 2] ** 2))
    errors = np.column_stack([log.reference[:, :3] - log.position, np.remainder(log.reference[:, 3] - yaw + np.pi, 2 * np.pi) - np.pi])
    camera_error = np.linalg.norm(log.camera_position - planned_camera, axis=1)
    return np.column_stack([
        log.t, log.position, log.quaternion, log.joints, log.rotor_speeds, log.reference,
        errors, log.camera_position, camera_error, log.contacts, log.saturated,
    ])


class Flight:
    """One robot in one MuJoCo world, driven tick by tick."""

    def __init__(self, model: mujoco.MjModel, config: Config, seed: int):
        self.model, self.data = model, mujoco.MjData(model)
        controller = config.controller
        self.dt = 1.0 / controller.rate_hz
        self.substeps = round(self.dt / model.opt.timestep)  # world.xml carries controller.physics_dt
        if abs(self.substeps * model.opt.timestep - self.dt) > 1e-9:
            raise UserError("controller.rate_hz: the control period must be a whole number of physics steps")
        self.rng = np.random.default_rng(np.random.SeedSequence([seed, 0xF1]))
        self.noise = controller.position_noise_std
        self.compensate_pitch = controller.compensate_arm_pitch
        uav = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, ROBOT_BODY)
        self.total_mass = float(model.body_subtreemass[uav])
        self.rotors = RotorModel(config.robot)
        self.config = config
        self.camera = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, CAMERA_SITE)
        self.robot_geom = model.geom_bodyid >= uav  # the robot is the last subtree of the world
        self.joint_qpos = np.array([model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)] for n in JOINT_NAMES])
        self.speeds = np.zeros(4)
        self.full_mass = np.zeros((model.nv, model.nv))
        # The controllers' arithmetic runs compiled, one call a tick (robot.kernel); what the call reads and
        # writes is fetched here once, as each attribute of MjData makes a new array object.
        from renderloop.robot.kernel import control_tick

        self._control_tick = control_tick
        self._qpos, self._qvel, self._bias, self._ctrl = self.data.qpos, self.data.qvel, self.data.qfrc_bias, self.data.ctrl
        self._quaternion = self.data.qpos[3:7]
        self._rotation_flat = np.empty(9)
        self._rotation = self._rotation_flat.reshape(3, 3)
        self._lag_alpha, self._top_w2 = self.rotors.lag_alpha(self.dt), float(self.rotors.max_speed_squared)
        self._noise = np.zeros(4)  # the position noise of a tick, and whether there is any
        self._noise[3] = self.noise > 0

    def reset(self, dofs: np.ndarray) -> None:
        """Hover at q* at rest, rotors at hover speed, controllers with empty integrators."""
        self.uav = UavController(self.config.controller, self.total_mass, self.rotors)
        self.arm = ArmController(self.config.controller, self.config.robot.arm.max_torque)
        data = self.data
        mujoco.mj_resetData(self.model, data)
        data.qpos[:3] = dofs[:3]
        data.qpos[3:7] = yaw_quaternion_wxyz(dofs[3])
        data.qpos[self.joint_qpos] = dofs[4:7]
        self.speeds = np.full(4, self.rotors.hover_speed(self.total_mass))
        mujoco.mj_forward(self.model, data)

    def snapshot(self) -> Snapshot:
        data = self.data
        return Snapshot(data.qpos[:3].copy(), data.qpos[XYZW], data.qpos[self.joint_qpos], data.site_xpos[self.camera].copy(),
                        data.site_xmat[self.camera].reshape(3, 3).copy(), self.contacts())

    def contacts(self) -> int:
        count = self.data.ncon
        if count == 0:
            return 0
        geoms = self.data.contact.geom[:count]
        return int(np.count_nonzero(self.robot_geom[geoms[:, 0]] != self.robot_geom[geoms[:, 1]]))

    def tick(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> None:
        """Controls for the reference (q*, q̇*, q̈*) at this instant, then one control period of physics."""
        model, data = self.model, self.data
        mujoco.mju_quat2Mat(self._rotation_flat, self._quaternion)
        if self.noise > 0:
            self._noise[:3] = self.rng.normal(0.0, self.noise, 3)
        mujoco.mj_fullM(model, data, self.full_mass)
        uav, arm = self.uav, self.arm
        uav.saturated = self._control_tick(
            uav.position.params, uav.position.state, uav.velocity.params, uav.velocity.state, uav.rate.params,
            uav.rate.state, uav.constants, arm.pid.params, arm.pid.state, arm.max_torque, self.compensate_pitch,
            self.rotors.K_inv, self._top_w2, self._lag_alpha, self.speeds, self._qpos, self._qvel, self.joint_qpos,
            self.full_mass, self._bias, self._rotation, self._noise, q, qd, qdd, self._ctrl,
        )
        mujoco.mj_step2(model, data)
        if self.substeps > 1:
            mujoco.mj_step(model, data, nstep=self.substeps - 1)
        mujoco.mj_step1(model, data)

    def body_rotation(self) -> np.ndarray:
        matrix = np.empty(9)
        mujoco.mju_quat2Mat(matrix, self.data.qpos[3:7])
        return matrix.reshape(3, 3)


class FlightRecorder:
    """The flight log, filled in place tick by tick: the state at each tick's instant, then the rotor speeds and
    saturation its controls gave. Rows grow by doubling, so a flight of unknown length (the Simulation API) records
    as cheaply as a planned one; a Snapshot object and its copies each tick cost a tenth of the tick."""

    def __init__(self, flight: Flight, capacity: int = 1024):
        self.flight, self.count = flight, 0
        self.pose = np.zeros((capacity, 10))  # x y z, qx qy qz qw, q1 q2 q3
        self.camera = np.zeros((capacity, 12))  # position, then the rotation's rows
        self.contacts = np.zeros(capacity, dtype=int)
        self.rotor_speeds = np.zeros((capacity, 4))
        self.saturated = np.zeros(capacity, dtype=bool)
        data = flight.data
        self._columns = np.r_[0:3, XYZW, flight.joint_qpos]
        self._qpos = data.qpos  # MjData's arrays are views of its buffers: fetched once, they stay current
        self._camera_position, self._camera_rotation = data.site_xpos[flight.camera], data.site_xmat[flight.camera]

    def state(self) -> int:
        """Record the state at this tick's instant, before its controls act; returns its row."""
        k = self.count
        if k == len(self.contacts):
            for name in ("pose", "camera", "contacts", "rotor_speeds", "saturated"):
                array = getattr(self, name)
                setattr(self, name, np.concatenate([array, np.zeros_like(array)]))
        self.pose[k] = self._qpos[self._columns]
        self.camera[k, :3] = self._camera_position
        self.camera[k, 3:] = self._camera_rotation
        self.contacts[k] = self.flight.contacts()
        self.count = k + 1
        return k

    def snapshot(self, k: int) -> Snapshot:
        pose, camera = self.pose[k], self.camera[k]
        return Snapshot(pose[:3], pose[3:7], pose[7:], camera[:3], camera[3:].reshape(3, 3), int(self.contacts[k]))

    def controls(self) -> None:
        """Record the rotor speeds and saturation that the last recorded state's controls gave."""
        self.rotor_speeds[self.count - 1] = self.flight.speeds
        self.saturated[self.count - 1] = self.flight.uav.saturated

    def log(self, t: np.ndarray, reference: np.ndarray) -> FlightLog:
        """The ticks recorded, at times `t` with references `reference` (one row each)."""
        n = self.count
        pose, camera = self.pose[:n].copy(), self.camera[:n].copy()
        return FlightLog(t=np.asarray(t), position=pose[:, :3], quaternion=pose[:, 3:7], joints=pose[:, 7:],
                         rotor_speeds=self.rotor_speeds[:n].copy(), reference=np.asarray(reference), camera_position=camera[:, :3],
                         camera_rotation=camera[:, 3:].reshape(n, 3, 3), contacts=self.contacts[:n].copy(),
                         saturated=self.saturated[:n].copy())


def resample(reference: Reference, rate_hz: float, hold: float) -> Reference:
    """The trajectory at the control rate, held at its last (resting) sample for `hold` seconds."""
    t = np.arange(0.0, reference.t[-1] + hold + 1e-9, 1.0 / rate_hz)
    index = np.minimum(np.searchsorted(reference.t, t - 1e-9), len(reference.t) - 1)
    exact = np.isclose(reference.t[index], t, atol=1e-9)
    if not exact.all():
        columns = [np.column_stack([np.interp(t, reference.t, a[:, k]) for k in range(7)]) for a in (reference.q, reference.qd, reference.qdd)]
        return Reference(t, *columns)
    return Reference(t, reference.q[index], reference.qd[index], reference.qdd[index])


def fly(model: mujoco.MjModel, config: Config, trajectory: Reference, hold: float = 1.0) -> FlightLog:
    flight = Flight(model, config, config.seed)
    reference = resample(trajectory, config.controller.rate_hz, hold)
    recorder = FlightRecorder(flight, len(reference.t))
    flight.reset(reference.q[0])
    for k in range(len(reference.t)):
        recorder.state()
        flight.tick(reference.q[k], reference.qd[k], reference.qdd[k])
        recorder.controls()
    return recorder.log(reference.t, reference.q)
