"""A simulation you can step: the robot, the reference it tracks, and the sensors that ride on it.

Physics and control are those of `renderloop fly` (`renderloop.sim.flight.Flight`: the same
controller, the same 2 ms physics step under a control tick), so stepping a trajectory
through `Simulation` gives the flight log `fly` gives. One `Simulation` owns time: the
controller ticks at its rate, sensors fire at theirs (a camera at its instants k / rate,
the control tick at or after each), and the planned motion can be replaced mid-flight
(`replan`, joined without a jump in position, velocity or acceleration).

    sim = Simulation(config)                    # the scene generated in memory; nothing is written
    sim.follow(sim.scan_trajectory())           # the paper's scan, planned with TOPP-RA
    camera = sim.add_camera()                   # renders every camera instant while flying
    sim.run_until(10.0)
    print(sim.state.position, len(camera.frames_until(sim.t)))

`Simulation(config, "runs/online")` writes the run directory instead, as `renderloop scene` and `renderloop plan` do
(each skipped when the directory already holds this config's files), and flies what those files hold. Both fly the
same: the plan in memory is what trajectory.csv gives back (`files.as_stored_trajectory`).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from pydantic import Field

from renderloop.config import Config
from renderloop.config.fields import Real, Strict, checked
from renderloop.errors import UserError
from renderloop.loop.reference import ReferencePlan
from renderloop.loop.sensors import Camera
from renderloop.parallel import Executor
from renderloop.planning.check import Clash, check_trajectory
from renderloop.planning.scan import plan_scan
from renderloop.planning.trajectory import Trajectory
from renderloop.planning.waypoints import read_waypoints
from renderloop.robot.kinematics import homogeneous
from renderloop.rundir import files, names
from renderloop.scene.generate import generate_scene
from renderloop.scene.model import Scene, read_scene
from renderloop.scene.stage import run_scene
from renderloop.scene.world import world_xml
from renderloop.sim.flight import Flight, FlightLog, FlightRecorder, Reference

HOLD = 1.0  # s the robot hovers at the end of its plan, as `renderloop fly` does
# The hover is sampled into the plan at the control rate (up to 1 kHz): 1000 s is 1 M samples of q*, q̇*, q̈*, 170 MB.
MAX_HOLD = 1000.0  # s
# A new yaw continues the old one modulo 2π (`ReferencePlan._path` unwraps it); within this float64 keeps it to 2e-12 rad.
MAX_YAW = 1e4  # rad
DOFS = ("x", "y", "z", "yaw", "q1", "q2", "q3")


class SimulationSettings(Strict):
    """The arguments of `Simulation` beside its config, bounded as the config's fields are."""

    hold: Real(0.0, MAX_HOLD) = Field(HOLD, description="Hover after the planned motion ends, s.")


@dataclass(frozen=True)
class RobotState:
    t: float  # simulation seconds
    position: np.ndarray  # body, world frame, m
    quaternion: np.ndarray  # body, qx qy qz qw
    velocity: np.ndarray  # body, world frame, m/s
    joints: np.ndarray  # q1..q3, rad
    camera_pose: np.ndarray  # T_world_optical (4, 4)


class Simulation:
    """One robot in one greenhouse, stepped a control period at a time: built in memory, or from the files of
    `run_dir` (made there unless they exist) when one is given."""

    def __init__(self, config: Config, run_dir: Path | str | None = None, hold: float = HOLD) -> None:
        if not isinstance(config, Config):
            raise UserError(f"Simulation: config is a {type(config).__name__}, not a renderloop Config (load_config)")
        # validated again: a Config changed by model_copy(update=...) rather than `override` is not, and would fail stages later
        config = config.override({}, "Simulation config")
        hold = checked(SimulationSettings, "Simulation", hold=hold).hold
        self.config, self.hold = config, hold
        self.run_dir = None if run_dir is None else Path(run_dir)
        if self.run_dir is None:
            self.scene: Scene = generate_scene(config)
            self.model = mujoco.MjModel.from_xml_string(world_xml(self.scene, config))
        else:
            run_scene(self.run_dir, config)  # skipped when the run directory already holds this config's scene
            self.scene = read_scene(self.run_dir)
            self.model = mujoco.MjModel.from_xml_path(str(self.run_dir / names.WORLD))
        self.flight = Flight(self.model, config, config.seed)
        self.rate_hz = config.controller.rate_hz
        self.plan: ReferencePlan | None = None
        self.tick = 0
        self.sensors: list[Camera] = []
        self._recorder = FlightRecorder(self.flight)

    # What it flies ---------------------------------------------------------------------------------------------------

    def scan_trajectory(self) -> Trajectory:
        """The scan of every plant (`renderloop plan`: elliptical waypoints, TOPP-RA), as trajectory.csv and
        waypoints.csv hold it; with a run directory, planned there unless it is there already."""
        if self.run_dir is None:
            plan = plan_scan(self.scene, self.config, self.model)
            table = files.as_stored_trajectory(plan.trajectory.table())
            times = files.as_stored_times(plan.trajectory.waypoint_times)
        else:
            from renderloop.planning.stage import run_plan

            run_plan(self.run_dir, self.config)
            table = files.read_trajectory(self.run_dir)
            times = np.array([w.time for w in read_waypoints(self.run_dir)])
        return Trajectory(table[:, 0], table[:, 1:8], table[:, 8:15], table[:, 15:22], times)

    def follow(self, trajectory: Trajectory | Reference) -> None:
        """Start over at the trajectory's first sample, hovering there at rest, and track it."""
        reference = Reference(trajectory.t, trajectory.q, trajectory.qd, trajectory.qdd)
        self.plan = ReferencePlan.of(reference, self.rate_hz, self.hold)
        self.flight.reset(self.plan.q[0])
        self.tick = 0
        self._recorder = FlightRecorder(self.flight)
        for sensor in self.sensors:
            sensor.restart()

    def replan(self, waypoints: np.ndarray, check: bool = False) -> np.ndarray:
        """From now on fly through `waypoints` (rows of q* = x, y, z, yaw, q1, q2, q3) instead of the rest of the plan,
        joined to the current reference without a jump; returns when the new plan passes each waypoint (simulation
        seconds; the last is when it ends). With `check`, the new motion must keep the planner's clearance from the
        greenhouse and stay inside it, or the plan is left as it was and a `Clash` says where it would hit and which
        waypoint the motion was heading for then. Waypoints that are not finite, lie outside the greenhouse room or
        bend a joint past the arm's limits are refused first, in one line naming the first such waypoint."""
        plan = self._require_plan()
        waypoints = self.check_waypoints(waypoints)
        trial = copy.deepcopy(plan) if check else plan
        times = trial.replan(self.tick, waypoints, self.config.planner, self.hold)
        if check:
            try:
                check_trajectory(self.model, trial.t[self.tick:], trial.q[self.tick:], tuple(self.scene.room))
            except Clash as clash:
                raise Clash(str(clash), clash.t, int(np.searchsorted(times, clash.t - 1e-9))) from None
            self.plan = trial
        return times

    def check_waypoints(self, waypoints: np.ndarray) -> np.ndarray:
        """`waypoints` as an (N, 7) float array of q*, or a UserError naming the first that cannot be flown: one not
        finite, one whose body lies outside the room (as `check_trajectory` bounds it), one whose yaw is beyond
        ±MAX_YAW, or one with a joint outside `robot.arm.joint_limits` (as inverse kinematics bounds it)."""
        try:
            rows = np.array(waypoints, dtype=float)
        except (TypeError, ValueError):
            raise UserError(f"waypoints: not an array of numbers ({type(waypoints).__name__})") from None
        rows = rows[None] if rows.shape == (len(DOFS),) else rows
        if rows.ndim != 2 or rows.shape[1] != len(DOFS) or len(rows) == 0:
            raise UserError(f"waypoints: shape {rows.shape} is not rows of q* ({', '.join(DOFS)})")
        length, width, height = self.scene.room
        low, high = self.config.robot.arm.joint_limits
        for index, (x, y, z, yaw, *joints) in enumerate(rows):
            where = f"waypoints: waypoint {index}"
            if not np.isfinite(rows[index]).all():
                raise UserError(f"{where} is not finite ({', '.join(f'{n}={v:g}' for n, v in zip(DOFS, rows[index]))})")
            if abs(x) > length / 2 or abs(y) > width / 2 or not 0.0 <= z <= height:
                raise UserError(f"{where} at x, y, z = {x:g}, {y:g}, {z:g} m is outside the greenhouse room "
                                f"(x within ±{length / 2:g} m, y within ±{width / 2:g} m, z from 0 to {height:g} m)")
            if abs(yaw) > MAX_YAW:
                raise UserError(f"{where} has yaw {yaw:g} rad, beyond ±{MAX_YAW:g} rad")
            for name, angle in zip(DOFS[4:], joints):
                if not low <= angle <= high:
                    raise UserError(f"{where} has {name} = {angle:g} rad, outside the arm's joint limits "
                                    f"[{low:g}, {high:g}] rad (robot.arm.joint_limits)")
        return rows

    def _require_plan(self) -> ReferencePlan:
        if self.plan is None:
            raise UserError("the simulation has no trajectory: call follow() first")
        return self.plan

    # Time -----------------------------------------------------------------------------------------------------------

    @property
    def t(self) -> float:
        plan = self._require_plan()
        return float(plan.t[self.tick]) if self.tick < len(plan) else self.tick / self.rate_hz

    @property
    def end(self) -> float:
        """When the planned motion ends (the hover after it is not part of it)."""
        return self._require_plan().end

    @property
    def finished(self) -> bool:
        """The plan and the hover after it have been flown."""
        return self.tick >= len(self._require_plan())

    def step(self) -> None:
        """One control period: sensors due at this instant fire, then the controller flies toward the reference."""
        plan = self._require_plan()
        snapshot = self._recorder.snapshot(self._recorder.state())
        now = self.t
        for sensor in self.sensors:
            sensor.observe(now, snapshot, plan.end)
        q, qd, qdd = plan.at(self.tick)
        self.flight.tick(q, qd, qdd)
        self._recorder.controls()
        self.tick += 1

    def run_until(self, t: float) -> None:
        """Step until simulation time `t` (the tick at or after it has not been flown yet)."""
        while self.t < t - 1e-9:
            self.step()

    def run(self) -> None:
        """Fly the rest of the plan and the hover after it."""
        while not self.finished:
            self.step()

    # What it knows ----------------------------------------------------------------------------------------------------

    @property
    def state(self) -> RobotState:
        snapshot, data = self.flight.snapshot(), self.flight.data
        return RobotState(self.t, snapshot.position, snapshot.quaternion, data.qvel[:3].copy(), snapshot.joints,
                          homogeneous(snapshot.camera_rotation, snapshot.camera_position))

    @property
    def reference(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q*, q̇*, q̈* the controller tracks at this instant."""
        return self._require_plan().at(self.tick)

    def log(self) -> FlightLog:
        """Everything flown so far, as `renderloop fly` logs it."""
        plan = self._require_plan()
        return self._recorder.log(plan.t[: self.tick], plan.q[: self.tick])

    # Sensors ----------------------------------------------------------------------------------------------------------

    def add_camera(self, rate_hz: float | None = None, backend: str | None = None, workers: int = 1,
                   executor: str = "local", address: str | None = None, encode: bool = False) -> Camera:
        """The arm's RGB-D camera at `rate_hz` (default the config's), rendered by `backend` (default the config's):
        raster in this process, Cycles in `workers` processes (or Ray tasks) so the physics keeps stepping. `encode`:
        the raster camera compresses every frame's PNGs (`frame.files`) on a thread as it renders, for a consumer that
        writes them all; otherwise a raster frame's files are compressed when first asked for (worker processes
        always send them)."""
        config = self.config if backend is None else \
            self.config.override({"renderer": {"backend": backend}}, f"unknown backend {backend!r}")
        camera = Camera(config, self.scene, self.rate_hz, rate_hz or self.config.camera.rate_hz,
                        Executor.of(executor, workers, address), encode)
        self.sensors.append(camera)
        return camera

    def close(self) -> None:
        for sensor in self.sensors:
            sensor.close()

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
