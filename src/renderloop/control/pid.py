"""A discrete PID on a vector with per-component gains and integrator clamping.

Components of one loop level (x, y, z of velocity; roll, pitch, yaw rates) share one
PID object: at 100 Hz in Python the per-call overhead, not the arithmetic, is the cost.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from renderloop.config import PID as Gains


class PID:
    def __init__(self, gains: Sequence[Gains], dt: float, integral_limit: float = np.inf, scale: Sequence[float] | None = None):
        """One Gains per component; `scale` multiplies every gain of a component (unit conversions)."""
        factor = np.ones(len(gains)) if scale is None else np.asarray(scale, dtype=float)
        self.p = factor * np.array([g.p for g in gains])
        self.i = factor * np.array([g.i for g in gains])
        self.d = factor * np.array([g.d for g in gains])
        self.has_d = bool(np.any(self.d))
        self.limit = np.array([np.inf if g.limit is None else g.limit for g in gains])
        self.dt = dt
        self.integral = np.zeros(len(gains))
        self.integral_limit = integral_limit
        self.previous: np.ndarray | None = None

    def __call__(self, error: np.ndarray, error_rate: np.ndarray | None = None) -> np.ndarray:
        """Output for `error`; `error_rate` replaces the finite difference when the caller knows it."""
        integral = self.integral + self.i * error * self.dt
        self.integral = np.minimum(np.maximum(integral, -self.integral_limit), self.integral_limit)
        output = self.p * error + self.integral
        if self.has_d:
            if error_rate is None:
                error_rate = 0.0 * error if self.previous is None else (error - self.previous) / self.dt
                self.previous = error
            output += self.d * error_rate
        return np.minimum(np.maximum(output, -self.limit), self.limit)
