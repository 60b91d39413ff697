"""The reference the robot tracks while flying: sampled at the control rate, replaceable mid-flight.

A replan starts from the reference's own state at the join (never the measured state, so the
controller sees no step). A quintic bridge of BRIDGE seconds leaves that state (position,
velocity and acceleration) and arrives, with position, velocity and acceleration matched, at
the start of a new TOPP-RA trajectory through the given waypoints; that trajectory starts
where constant acceleration would have taken the robot, at that velocity, and runs straight
on (a braking distance) before it turns, so the limits always leave room to make the turn.
The bridge only eases the acceleration from the old value to the new one: it overshoots the
two by at most 0.375 of their difference, where blending whole trajectories would triple it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderloop.config import PlannerConfig
from renderloop.errors import UserError
from renderloop.planning.trajectory import path_norm, time_parameterize
from renderloop.sim.flight import Reference, resample

BRIDGE = 0.2  # s from the old reference's state to the new trajectory's first sample


def quintic_bridge(start: tuple[np.ndarray, ...], end: tuple[np.ndarray, ...], duration: float,
                   times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q, q̇, q̈ at `times` (0..duration) of the quintic that joins (q, q̇, q̈) `start` to `end` (per DoF)."""
    q0, v0, a0 = start
    q1, v1, a1 = end
    T = duration
    rhs = np.stack([q1 - (q0 + v0 * T + a0 * T**2 / 2), v1 - (v0 + a0 * T), a1 - a0])
    system = np.array([[T**3, T**4, T**5], [3 * T**2, 4 * T**3, 5 * T**4], [6 * T, 12 * T**2, 20 * T**3]])
    c3, c4, c5 = np.linalg.solve(system, rhs)
    t = np.asarray(times)[:, None]
    q = q0 + v0 * t + a0 / 2 * t**2 + c3 * t**3 + c4 * t**4 + c5 * t**5
    qd = v0 + a0 * t + 3 * c3 * t**2 + 4 * c4 * t**3 + 5 * c5 * t**4
    qdd = a0 + 6 * c3 * t + 12 * c4 * t**2 + 20 * c5 * t**3
    return q, qd, qdd


@dataclass
class ReferencePlan:
    """q*, q̇*, q̈* at every control tick; after the last sample the reference rests where it ended."""

    rate_hz: float
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    end: float  # s, when the planned motion ends (the camera records until then)

    @classmethod
    def of(cls, trajectory: Reference, rate_hz: float, hold: float) -> ReferencePlan:
        sampled = resample(trajectory, rate_hz, hold)
        return cls(rate_hz, sampled.t, sampled.q, sampled.qd, sampled.qdd, float(trajectory.t[-1]))

    def __len__(self) -> int:
        return len(self.t)

    def at(self, tick: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The reference at a tick; past the last sample, the last position at rest."""
        if tick < len(self.t):
            return self.q[tick], self.qd[tick], self.qdd[tick]
        return self.q[-1], np.zeros(7), np.zeros(7)

    def replan(self, tick: int, waypoints: np.ndarray, planner: PlannerConfig, hold: float) -> np.ndarray:
        """From `tick` on, fly through `waypoints` (rows of q*), joined to the current reference without a jump;
        returns when the new reference passes each waypoint (simulation seconds, the last one its end).

        The new motion keeps the current speed where the limits allow the turn into the new path; where they do not
        (a waypoint close ahead, or behind), it brakes to a stop first, on a quintic, and leaves from rest."""
        self._rest_until(tick)
        state = self.at(tick)
        waypoints = np.asarray(waypoints, dtype=float).reshape(-1, 7)
        velocity = planner.limit_margin * np.asarray(planner.velocity_limits)
        acceleration = planner.limit_margin * np.asarray(planner.acceleration_limits)
        q0, qd0, qdd0 = state
        bridge = round(BRIDGE * self.rate_hz) / self.rate_hz
        start_qd = np.clip(qd0 + qdd0 * bridge, -velocity, velocity)
        start_q = q0 + (qd0 + start_qd) / 2 * bridge
        try:
            if path_norm(start_qd) < 1e-9:
                raise UserError("at rest")  # nothing to keep: leave from rest below
            braking = float(np.max(np.abs(start_qd) / acceleration))  # s to stop at the limits
            lead = start_q + start_qd * braking  # twice the braking distance: room for the turn after it
            new = time_parameterize(self._path(q0, [start_q, lead], waypoints), planner, start_velocity=start_qd)
        except UserError:
            stop = max(bridge, 2 * float(np.max(np.abs(qd0) / acceleration)))  # braking at half the limits
            bridge = round(stop * self.rate_hz) / self.rate_hz
            start_q = q0 + qd0 * bridge / 2 + qdd0 * bridge**2 / 12  # where a quintic from this state comes to rest
            new = time_parameterize(self._path(q0, [start_q], waypoints), planner)
        tail = resample(Reference(new.t, new.q, new.qd, new.qdd), self.rate_hz, hold)
        ticks = round(bridge * self.rate_hz)
        joined = quintic_bridge(state, (tail.q[0], tail.qd[0], tail.qdd[0]), bridge, np.arange(ticks) / self.rate_hz)
        t0 = tick / self.rate_hz
        self.t = np.concatenate([self.t[:tick], t0 + np.arange(ticks + len(tail.t)) / self.rate_hz])
        self.q = np.vstack([self.q[:tick], joined[0], tail.q])
        self.qd = np.vstack([self.qd[:tick], joined[1], tail.qd])
        self.qdd = np.vstack([self.qdd[:tick], joined[2], tail.qdd])
        self.end = t0 + bridge + float(new.t[-1])
        return t0 + bridge + new.waypoint_times[-len(waypoints):]

    def _rest_until(self, tick: int) -> None:
        """Samples at rest where the plan ended, up to `tick`: a replan after the hover joins a reference that exists."""
        missing = tick - len(self.t)
        if missing > 0:
            self.t = np.concatenate([self.t, (len(self.t) + np.arange(missing)) / self.rate_hz])
            self.q = np.vstack([self.q, np.repeat(self.q[-1:], missing, axis=0)])
            self.qd = np.vstack([self.qd, np.zeros((missing, 7))])
            self.qdd = np.vstack([self.qdd, np.zeros((missing, 7))])

    @staticmethod
    def _path(q0: np.ndarray, start: list[np.ndarray], waypoints: np.ndarray) -> np.ndarray:
        path = np.vstack([*start, waypoints])
        path[:, 3] = q0[3] + np.unwrap(path[:, 3] - q0[3])  # the new yaw continues the old one, no 2π turn
        return path
