"""Joint PIDs of the arm, acting through the arm's mass matrix with gravity compensation.

The PID sets a joint acceleration (the trajectory's plus the feedback); the mass
matrix and the bias forces of the model turn it into torques, so one set of gains
fits all three joints although their loads differ tenfold. The arithmetic is
compiled (robot.kernel.arm_torques).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from renderloop.config import ControllerConfig
from renderloop.control.pid import PID, floats3


class ArmController:
    def __init__(self, config: ControllerConfig, max_torque: float):
        from renderloop.robot import kernel  # numba loads with the first controller, not with the package

        self.pid = PID([config.joints] * 3, 1.0 / config.rate_hz, integral_limit=5.0)
        self.max_torque = float(max_torque)
        self._torques = kernel.arm_torques

    def torques(
        self, q: Sequence[float], qd: Sequence[float], q_ref: Sequence[float], qd_ref: Sequence[float],
        qdd_ref: Sequence[float], mass_matrix: np.ndarray, bias: Sequence[float],
    ) -> tuple[np.ndarray, np.ndarray]:
        """Joint torques, and the joint accelerations they ask for (the body controller's feed-forward)."""
        torques, acceleration = self._torques(
            self.pid.params, self.pid.state, self.max_torque, floats3(q), floats3(qd), floats3(q_ref), floats3(qd_ref),
            floats3(qdd_ref), np.asarray(mass_matrix, dtype=float), np.asarray(bias, dtype=float),
        )
        return np.array(torques), np.array(acceleration)
