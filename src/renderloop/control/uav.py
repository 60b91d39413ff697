"""Cascade PID of the quadrotor: position → velocity → attitude → body rates → wrench → rotor speeds.

The velocity loop asks for an acceleration (plus the trajectory's as feed-forward);
that acceleration and gravity fix the thrust direction, the planned yaw fixes the
rest of the wanted attitude (the geometric construction of Lee et al., which stays
right at large tilts and any yaw). The attitude error on SO(3) drives body-rate
commands, and the rate loop asks for angular accelerations. Those become moments
through the rotational rows of the whole robot's mass matrix and its bias forces:
the arm quadruples the yaw inertia, hangs in front of the centre of mass and pushes
back on the body when it moves, and a controller that ignored that would lag every turn.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderloop.config import ControllerConfig
from renderloop.control.pid import PID
from renderloop.robot.rotors import GRAVITY, RotorModel


@dataclass
class UavState:
    position: np.ndarray  # world
    velocity: np.ndarray  # world
    rotation: np.ndarray  # body to world
    body_rates: np.ndarray  # body frame


@dataclass
class UavReference:
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    yaw: float
    yaw_rate: float
    yaw_acceleration: float


@dataclass
class RigidBodyTerms:
    """The model's rotational equations M_rot · [a_world, α_body, q̈_arm] + bias = moments."""

    rotational_mass: np.ndarray  # (3, 9) rows of the joint-space mass matrix for the body's rotation
    bias: np.ndarray  # (3,) gravity and Coriolis moments in the body frame
    arm_acceleration: np.ndarray  # (3,) the joint accelerations the arm is about to be asked for


def _vee(matrix: np.ndarray) -> np.ndarray:
    return np.array([matrix[2, 1], matrix[0, 2], matrix[1, 0]])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """np.cross costs ~30 µs on 3-vectors; this costs 2."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def wanted_attitude(thrust_direction: np.ndarray, yaw: float) -> np.ndarray:
    """Rotation whose z axis is the thrust direction and whose x axis points along `yaw`."""
    side = _cross(thrust_direction, np.array([math.cos(yaw), math.sin(yaw), 0.0]))
    side /= math.sqrt(side @ side)
    return np.column_stack([_cross(side, thrust_direction), side, thrust_direction])


class UavController:
    def __init__(self, config: ControllerConfig, total_mass: float, rotors: RotorModel):
        dt = 1.0 / config.rate_hz
        self.config = config
        self.mass = total_mass
        self.rotors = rotors
        self.position = PID([config.position_xy, config.position_xy, config.position_z], dt)
        self.velocity = PID([config.velocity_xy, config.velocity_xy, config.velocity_z], dt, integral_limit=3.0,
                            scale=[GRAVITY, GRAVITY, 1.0])  # xy gains are rad of tilt per m/s
        self.rate = PID([config.rate, config.rate, config.yaw_rate], dt, integral_limit=20.0)
        self.attitude_gains = np.array([config.attitude.p, config.attitude.p, config.yaw.p])
        self.tilt_slope = math.tan(config.max_tilt)
        self.saturated = False

    def acceleration(self, state: UavState, reference: UavReference) -> np.ndarray:
        """Outer loops: the world acceleration wanted, tilt-limited."""
        velocity = reference.velocity + self.position(reference.position - state.position)
        wanted = reference.acceleration + self.velocity(velocity - state.velocity)
        horizontal = math.hypot(wanted[0], wanted[1])
        reach = (GRAVITY + wanted[2]) * self.tilt_slope
        if horizontal > reach > 0:
            wanted[:2] *= reach / horizontal
        return wanted

    def rotor_speeds(self, state: UavState, reference: UavReference, terms: RigidBodyTerms) -> np.ndarray:
        acceleration = self.acceleration(state, reference)
        force = self.mass * (acceleration + np.array([0.0, 0.0, GRAVITY]))
        thrust = max(float(force @ state.rotation[:, 2]), 0.0)
        wanted = wanted_attitude(force / math.sqrt(force @ force), reference.yaw)
        rotation = state.rotation
        attitude_error = 0.5 * _vee(wanted.T @ rotation - rotation.T @ wanted)
        to_body = rotation.T @ wanted
        rate_error = to_body @ np.array([0.0, 0.0, reference.yaw_rate]) - self.attitude_gains * attitude_error - state.body_rates
        angular_acceleration = to_body @ np.array([0.0, 0.0, reference.yaw_acceleration])
        angular_acceleration += self.rate(rate_error)
        generalized = np.concatenate([acceleration, angular_acceleration, terms.arm_acceleration])
        moments = terms.rotational_mass @ generalized + terms.bias
        speeds, self.saturated = self.rotors.mix(np.array([thrust, moments[0], moments[1], moments[2]]))
        return speeds
