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
from renderloop.control.pid import PID, floats3
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


class UavController:
    """Gains, constants and loop states in arrays; the cascade itself is compiled (robot.kernel.uav_wrench)."""

    def __init__(self, config: ControllerConfig, total_mass: float, rotors: RotorModel):
        from renderloop.robot import kernel  # numba loads with the first controller, not with the package

        dt = 1.0 / config.rate_hz
        self.config = config
        self.mass = total_mass
        self.rotors = rotors
        self.position = PID([config.position_xy, config.position_xy, config.position_z], dt)
        self.velocity = PID([config.velocity_xy, config.velocity_xy, config.velocity_z], dt, integral_limit=3.0,
                            scale=[GRAVITY, GRAVITY, 1.0])  # xy gains are rad of tilt per m/s
        self.rate = PID([config.rate, config.rate, config.yaw_rate], dt, integral_limit=20.0)
        self.attitude_gains = np.array([config.attitude.p, config.attitude.p, config.yaw.p], dtype=float)
        self.tilt_slope = math.tan(config.max_tilt)
        self.constants = np.zeros(kernel.UAV_CONSTANTS)
        self.constants[kernel.MASS] = total_mass
        self.constants[kernel.TILT_SLOPE] = self.tilt_slope
        self.constants[kernel.G] = GRAVITY
        self.constants[kernel.ATTITUDE_GAIN:kernel.ATTITUDE_GAIN + 3] = self.attitude_gains
        self.saturated = False
        self._wrench = kernel.uav_wrench

    def wrench(self, state: UavState, reference: UavReference, terms: RigidBodyTerms) -> tuple[float, float, float, float]:
        """The wrench the cascade asks for: thrust along body z, moments about body x, y, z."""
        position, velocity, rate = self.position, self.velocity, self.rate
        return self._wrench(
            position.params, position.state, velocity.params, velocity.state, rate.params, rate.state, self.constants,
            floats3(state.position), floats3(state.velocity), np.asarray(state.rotation, dtype=float),
            floats3(state.body_rates), floats3(reference.position), floats3(reference.velocity),
            floats3(reference.acceleration), float(reference.yaw), float(reference.yaw_rate),
            float(reference.yaw_acceleration), np.asarray(terms.rotational_mass, dtype=float),
            np.asarray(terms.bias, dtype=float), floats3(terms.arm_acceleration),
        )

    def rotor_speeds(self, state: UavState, reference: UavReference, terms: RigidBodyTerms) -> np.ndarray:
        speeds, self.saturated = self.rotors.mix(np.array(self.wrench(state, reference, terms)))
        return speeds
