"""Joint PIDs of the arm, acting through the arm's mass matrix with gravity compensation.

The PID sets a joint acceleration (the trajectory's plus the feedback); the mass
matrix and the bias forces of the model turn it into torques, so one set of gains
fits all three joints although their loads differ tenfold.
"""

from __future__ import annotations

import numpy as np

from renderloop.config import ControllerConfig
from renderloop.control.pid import PID


class ArmController:
    def __init__(self, config: ControllerConfig, max_torque: float):
        self.pid = PID([config.joints] * 3, 1.0 / config.rate_hz, integral_limit=5.0)
        self.max_torque = max_torque

    def torques(
        self, q: np.ndarray, qd: np.ndarray, q_ref: np.ndarray, qd_ref: np.ndarray, qdd_ref: np.ndarray,
        mass_matrix: np.ndarray, bias: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Joint torques, and the joint accelerations they ask for (the body controller's feed-forward)."""
        acceleration = qdd_ref + self.pid(q_ref - q, qd_ref - qd)
        torques = mass_matrix @ acceleration + bias
        return np.minimum(np.maximum(torques, -self.max_torque), self.max_torque), acceleration
