"""A discrete PID on a 3-vector with per-component gains and integrator clamping.

The components of one loop level (x, y, z of velocity; roll, pitch, yaw rates; the
three joints) share one PID object. Its gains and state are small arrays, and the
update is compiled (robot.kernel), where Flight's control tick runs it too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from renderloop.config import PID as Gains


def floats3(values: Sequence[float]) -> tuple[float, float, float]:
    """A 3-vector as the compiled functions take it: a tuple of Python floats."""
    a, b, c = values
    return float(a), float(b), float(c)


class PID:
    def __init__(self, gains: Sequence[Gains], dt: float, integral_limit: float = np.inf, scale: Sequence[float] | None = None):
        """One Gains per component; `scale` multiplies every gain of a component (unit conversions)."""
        from renderloop.robot import kernel  # numba loads with the first controller, not with the package

        if len(gains) != 3:
            raise ValueError(f"a PID has 3 components, got {len(gains)} gains")
        factor = np.ones(3) if scale is None else np.asarray(scale, dtype=float)
        params = np.zeros(kernel.PID_PARAMS)
        params[kernel.P_GAIN:kernel.P_GAIN + 3] = factor * np.array([g.p for g in gains])
        params[kernel.I_GAIN:kernel.I_GAIN + 3] = factor * np.array([g.i for g in gains])
        params[kernel.D_GAIN:kernel.D_GAIN + 3] = factor * np.array([g.d for g in gains])
        limits = [math.inf if g.limit is None else float(g.limit) for g in gains]
        params[kernel.LIMIT:kernel.LIMIT + 3] = limits
        params[kernel.INTEGRAL_LIMIT] = integral_limit
        params[kernel.DT] = dt
        params[kernel.HAS_D] = np.any(params[kernel.D_GAIN:kernel.D_GAIN + 3])
        params[kernel.BOUNDS_INTEGRAL] = math.isfinite(integral_limit)
        params[kernel.BOUNDS_OUTPUT] = any(math.isfinite(c) for c in limits)
        self.params = params
        self.state = np.zeros(kernel.PID_STATE)  # integral, previous error, whether there is one
        self._update = kernel.pid_update

    def __call__(self, error: Sequence[float], error_rate: Sequence[float] | None = None) -> np.ndarray:
        """Output for `error`; `error_rate` replaces the finite difference when the caller knows it."""
        e0, e1, e2 = floats3(error)
        if error_rate is None:
            return np.array(self._update(self.params, self.state, e0, e1, e2, False, 0.0, 0.0, 0.0))
        r0, r1, r2 = floats3(error_rate)
        return np.array(self._update(self.params, self.state, e0, e1, e2, True, r0, r1, r2))
