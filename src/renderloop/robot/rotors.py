"""Rotor model and the input mapping u = K · [w1² .. w4²] of a planar quadrotor.

u = [net thrust, roll moment, pitch moment, yaw moment] in the body frame
(x forward, y left, z up). Each rotor i at (x_i, y_i) gives thrust F_i = kf w_i²
along body z and a drag moment d_i km F_i about body z, d_i = ±1 alternating, so
the yaw moment of a pair is cancelled in hover.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from renderloop.config import RobotConfig

GRAVITY = 9.81


@dataclass(frozen=True)
class RotorGeometry:
    positions: np.ndarray  # (4, 2) rotor axes in the body x-y plane, m
    drag_signs: np.ndarray  # (4,) sign of each rotor's reaction moment about body +z


def rotor_geometry(arm_length: float, layout: str) -> RotorGeometry:
    """'x': rotors at 45°, 135°, 225°, 315° (front-left first); '+': on the body axes, front first."""
    first = math.pi / 4 if layout == "x" else 0.0
    angles = first + np.arange(4) * (math.pi / 2)
    positions = arm_length * np.column_stack([np.cos(angles), np.sin(angles)])
    return RotorGeometry(positions=positions, drag_signs=np.array([1.0, -1.0, 1.0, -1.0]))


def input_mapping(geometry: RotorGeometry, kf: float, km: float) -> np.ndarray:
    """The 4x4 matrix K with u = K · w², from the rotor positions and coefficients."""
    x, y = geometry.positions[:, 0], geometry.positions[:, 1]
    return kf * np.vstack([np.ones(4), y, -x, km * geometry.drag_signs])


class RotorModel:
    """Rotor speeds <-> body wrench, with saturation and an optional first-order motor lag."""

    def __init__(self, robot: RobotConfig):
        from renderloop.robot import kernel  # numba loads with the first rotor model, not with the package

        rotor = robot.rotor
        self.kf = rotor.kf
        self.km = rotor.km
        self.max_speed = rotor.max_speed
        self.max_speed_squared = rotor.max_speed**2
        self.time_constant = rotor.time_constant
        self.geometry = rotor_geometry(robot.arm_length, rotor.layout)
        self.K = input_mapping(self.geometry, self.kf, self.km)
        self.K_inv = np.linalg.inv(self.K)
        self._mix, self._lag = kernel.mix, kernel.lag

    def wrench(self, speeds: np.ndarray) -> np.ndarray:
        """[thrust, Mx, My, Mz] produced by rotor speeds in rad/s."""
        return self.K @ np.square(speeds)

    def mix(self, wrench: np.ndarray) -> tuple[np.ndarray, bool]:
        """Rotor speeds for a wanted wrench, each clamped to [0, max_speed], and whether any was clamped.

        The mixer may ask for a negative w² (a moment too large for the thrust): that
        rotor stops, which is what a real ESC does too.
        """
        thrust, mx, my, mz = (float(w) for w in wrench)
        speeds, saturated = self._mix(self.K_inv, self.max_speed_squared, thrust, mx, my, mz)
        return np.array(speeds), saturated

    def hover_speed(self, total_mass: float, gravity: float = GRAVITY) -> float:
        return math.sqrt(total_mass * gravity / (4.0 * self.kf))

    def lag_alpha(self, dt: float) -> float:
        """The share of the way to the commanded speeds a held command covers in dt; -1: no lag, all of it."""
        return -1.0 if self.time_constant == 0.0 else 1.0 - math.exp(-dt / self.time_constant)

    def lag(self, current: np.ndarray, commanded: np.ndarray, dt: float) -> np.ndarray:
        """One step of the motor's first-order lag, exact for a command held over dt."""
        speeds = np.array(current, dtype=float)
        c0, c1, c2, c3 = (float(c) for c in commanded)
        self._lag(speeds, self.lag_alpha(dt), c0, c1, c2, c3)
        return speeds
