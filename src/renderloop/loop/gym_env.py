"""`renderloop/PepperScan-v0`: active perception of one pepper plant as a Gymnasium environment.

One episode is one plant of a greenhouse generated from the episode's seed. The robot
starts hovering at a start view of the plant and has taken a frame there; each action
picks the next viewpoint around the plant, the robot flies there in the simulation
(`renderloop.loop.simulation.Simulation`: the same physics, controller and TOPP-RA
replanning as `renderloop run --online`) until the planned motion ends and the camera is
within 1 cm of where it was sent (at most 1 s more), the camera takes one frame (rendered
as `renderloop render` renders a pose: the same renderer, sensor models and per-frame
seeds), the detector and the fruit points run on it (`OnlinePerception`) and the online
count (`OnlineCounter`) is updated. The reward is the fruit newly confirmed on the plant
less the flight time the view cost.

    import gymnasium, renderloop
    env = gymnasium.make("renderloop/PepperScan-v0", max_views=8)
    observation, info = env.reset(seed=0)
    observation, reward, terminated, truncated, info = env.step(env.action_space.sample())

Views. A view is (azimuth, height, distance) about the plant: the camera sits `distance`
(horizontally) from the plant's axis, in the direction `azimuth` (rad, counter-clockwise
from world +x: 0 faces the plant from +x, π from -x), `height` above the middle of the
canopy (`renderloop.planning.waypoints.scan_target`), and looks at that middle with no
roll (`look_at`); inverse kinematics (`camera_pose_to_dofs`) gives the robot's q*. On a
canopy taller than 1 m (the greenhouse preset's) the height reaches to 0.2 m inside its
ends, and the camera looks at the plant's axis nearest its own height, at most 0.3 m from
it (`renderloop.loop.viewpoints.aim_point`).

Action: a float32 Box of 3 in [-1, 1], scaled linearly to the view:
    azimuth  = π a[0]                                  rad, in [-π, π]
    height   = 0.3 a[1]                                m, in [-0.3, 0.3] (tall canopies: see above)
    distance = 0.55 + 0.2 a[2]                         m, in [0.35, 0.75]
Values outside [-1, 1] are clipped (and NaN reads as 0); anything but 3 numbers is a ValueError.

Projection: the action is never refused. A view is reachable when the arm's inverse
kinematics has a solution, and the path to it is clear: the robot flies from the current
view along the ring (the views in between, azimuth along the shorter way round, height and
distance linearly), through waypoints at most 10° apart, and every q* on the straight
segments between them (every 2 cm) is checked in MuJoCo against the greenhouse with the
planner's clearance (`renderloop.planning.check.check_trajectory`: nothing within 3 cm,
the body inside the room). When the requested view is not reachable, the flown view is
the reachable view nearest to it in azimuth on its ring (same height and distance, 5°
steps, ties broken towards the current azimuth); when none on that ring is, the same search
runs on rings whose height and distance are moved a quarter, a half, three quarters of the
way back towards the current view's, and finally on the current view's own ring, where
the current view itself is always reachable. A view within 1 mm of the current one is the
current one: the robot then hovers there for 0.5 s and takes another frame (as it does in
the rare case that TOPP-RA finds no parameterisation of the flight).

Observation (a Dict):
    rgb          (H, W, 3) uint8, the frame taken at the view (the colour sensor's when the config has one)
    depth        (H, W) float32, planar depth in m as the sensor reports it (0 = no return)
    camera_pose  (7,) float32, the camera's optical frame in the world: x y z qx qy qz qw
    counter      (4,) float32: fruit confirmed on this plant so far, the ripe among them,
                 frames taken (the start view included), flight time so far (s)

Reward: the change in the number of fruit confirmed on the plant (counted clusters with at
least `counting.min_views` detections, the count's own rule) minus `time_cost` times the
flight seconds of the step. The count of all frames so far is redone at every step, so two
clusters merging can lower it: summed over an episode the reward is the final confirmed
count less the time cost of the whole flight.

Episode end: `terminated` once `max_views` views have been flown (the start view is not
one of them); `truncated` only when `max_flight_time` is given and the flight time so far
reaches it. `info`: the plant and the scene seed, the plant's true fruit (`true_fruit`,
`true_ripe`, from the scene), the confirmed counts, the view requested (after clipping)
and the view flown (`view`: azimuth, height, distance), whether it was projected, the q*
flown to, and the step's flight time.

`reset(seed=...)` draws, from the environment's generator, the scene seed, the plant (a
bearing one) and the start view's side (azimuth 0 or π, height 0, distance 0.55 m; the
nearest reachable azimuth on that ring); `options` may fix `scene_seed` and `plant`. Each scene's
files live in a directory of the environment's own temporary directory (or of `run_dir`),
kept for the last few scenes so that a seed that comes back resets quickly; `close()`
removes the temporary directory. The detector is built once per environment.
"""

from __future__ import annotations

import math
import shutil
import tempfile
import weakref
from collections import OrderedDict
from pathlib import Path
from typing import Any, Literal

import gymnasium
import numpy as np
from gymnasium import spaces
from pydantic import Field
from scipy.spatial.transform import Rotation

from renderloop.config import Config, load_config
from renderloop.config.fields import Count, Real, Strict, checked
from renderloop.counting.online import OnlineCounter
from renderloop.errors import UserError
from renderloop.io.tum import as_stored
from renderloop.loop.sensors import Frame
from renderloop.loop.simulation import MAX_HOLD, Simulation
from renderloop.loop.perceive import OnlinePerception
from renderloop.loop.viewpoints import (
    DISTANCE_RANGE,
    Projector,
    View,
    action_to_view,
)
from renderloop.render.executor import FrameWorker
from renderloop.render.frames import MAX_DEPTH, stored_images
from renderloop.robot.kinematics import (
    dofs_to_camera_pose,
    homogeneous,
)
from renderloop.rundir import names
from renderloop.sim.flight import Reference

ENV_ID = "renderloop/PepperScan-v0"

STAY = 0.5  # s the robot hovers when the view flown is the view it is at
SETTLE_TOLERANCE = 0.01  # m: the camera counts as arrived this close to its planned position
MAX_SETTLE = 1.0  # s it may take after the planned motion ends to come that close
SCENES_KEPT = 16  # scene directories kept in the temporary directory (a seed that comes back resets fast)
SCENE_SEEDS = 2**31  # scene seeds are drawn from [0, SCENE_SEEDS)
MARGIN = np.float32(0.01)  # on the camera pose's bounds: the room, and unit quaternions, as float32 rounds them
# The simulation's hover after its plan holds every view's STAY, so the views are as many as MAX_HOLD leaves room for.
MAX_VIEWS = int((MAX_HOLD - MAX_SETTLE) / STAY) - 1


class ScanSettings(Strict):
    """The environment's arguments beside its config, bounded as the config's fields are (a NaN cost would make
    every reward NaN; a million views a hover of days sampled into memory)."""

    max_views: Count(1, MAX_VIEWS) = Field(8, description="Views an episode flies (the start view is not one).")
    time_cost: Real(0.0, 100.0) = Field(0.05, description="Reward lost per second of flight, fruit/s.")
    max_flight_time: Real(0.0, 86_400.0, low_open=True) | None = Field(
        None, description="Flight time at which an episode is truncated, s; None: never.")
    render_mode: Literal["rgb_array"] | None = Field(None, description="What `render()` returns: the last frame's RGB.")


def pose_vector(pose: np.ndarray) -> np.ndarray:
    """T_world_optical as x y z qx qy qz qw."""
    return np.concatenate([pose[:3, 3], Rotation.from_matrix(pose[:3, :3]).as_quat()]).astype(np.float32)


class PepperScanEnv(gymnasium.Env):
    """Scan one pepper plant from viewpoints an agent chooses (module docstring: spaces, projection, reward)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 2}

    def __init__(self, config: Config | None = None, backend: str | None = "raster", max_views: int = 8,
                 time_cost: float = 0.05, max_flight_time: float | None = None, render_mode: str | None = None,
                 run_dir: Path | str | None = None) -> None:
        """`config`: the greenhouse, robot, camera, detector and counting (default: the demo preset); `backend`:
        the renderer (None keeps the config's); `run_dir`: where each scene's files go (default a temporary
        directory that `close()` removes). The other arguments are bounded by `ScanSettings`: one out of its range
        is a ValueError (UserError) in the CLI's one line, before anything is made."""
        settings = checked(ScanSettings, "PepperScanEnv", max_views=max_views, time_cost=time_cost,
                           max_flight_time=max_flight_time, render_mode=render_mode)
        config = config if config is not None else load_config("demo")
        if not isinstance(config, Config):
            raise UserError(f"PepperScanEnv: config is a {type(config).__name__}, not a renderloop Config (load_config)")
        if backend is not None:  # None keeps the config's
            config = config.override({"renderer": {"backend": backend}}, "PepperScanEnv config")
        self.config, self.max_views, self.time_cost = config, settings.max_views, settings.time_cost
        self.max_flight_time, self.render_mode = settings.max_flight_time, settings.render_mode
        self._owned = run_dir is None
        self.run_dir = Path(tempfile.mkdtemp(prefix="renderloop-gym-")) if run_dir is None else Path(run_dir)
        # an environment never closed still leaves no temporary directory behind once it is collected (or at exit)
        self._remove = weakref.finalize(self, shutil.rmtree, self.run_dir, True) if self._owned else None
        self._scenes: OrderedDict[int, Path] = OrderedDict()

        height, width = config.camera.height, config.camera.width
        length, room_width, room_height = config.greenhouse.size
        pose_low = np.array([-length / 2, -room_width / 2, 0.0, -1, -1, -1, -1], np.float32) - MARGIN
        pose_high = np.array([length / 2, room_width / 2, room_height, 1, 1, 1, 1], np.float32) + MARGIN
        self.observation_space = spaces.Dict({
            "rgb": spaces.Box(0, 255, (height, width, 3), np.uint8),
            "depth": spaces.Box(np.float32(0.0), np.float32(MAX_DEPTH), (height, width), np.float32),  # as PNG holds it
            "camera_pose": spaces.Box(pose_low, pose_high),
            "counter": spaces.Box(np.float32(0.0), np.inf, (4,), np.float32),
        })
        self.action_space = spaces.Box(-1.0, 1.0, (3,), np.float32)

        self.perception = OnlinePerception(config, None)  # the detector, built once; each episode gives it a counter
        self.sim: Simulation | None = None
        self.camera: FrameWorker | None = None
        self._camera_seed: int | None = None
        self._frame: Frame | None = None
        self._closed = False

    # Episodes ---------------------------------------------------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        if self._closed:
            raise UserError("PepperScanEnv: the environment is closed")
        super().reset(seed=seed)
        options = options or {}
        scene_seed = int(self.np_random.integers(SCENE_SEEDS))
        pick, side = float(self.np_random.random()), int(self.np_random.integers(2))
        scene_seed = int(options.get("scene_seed", scene_seed))
        config = self.config.override({"seed": scene_seed})
        if self.sim is not None:
            self.sim.close()
        self.sim = Simulation(config, self._scene_dir(config), hold=MAX_SETTLE + (self.max_views + 1) * STAY)
        scene = self.sim.scene
        bearing = [p for p in scene.plants if p.bearing] or list(scene.plants)
        if "plant" in options:
            if not 0 <= int(options["plant"]) < len(scene.plants):
                raise UserError(f"options: plant {options['plant']} (the scene has {len(scene.plants)} plants)")
            self.plant = scene.plant(int(options["plant"]))
        else:
            self.plant = bearing[min(int(pick * len(bearing)), len(bearing) - 1)]
        if self._camera_seed != scene_seed:  # a renderer holds one scene: the same scene keeps it
            if self.camera is not None:
                self.camera.close()
            self.camera = FrameWorker(config, scene)
            self._camera_seed = scene_seed
        self.perception.counter = OnlineCounter(scene, config.counting, scene_seed)
        self.perception.frames = []
        self.projector = Projector(config, scene, self.plant, self.sim.run_dir / names.WORLD)
        peppers = scene.peppers_of(self.plant.id)
        self.truth = (len(peppers), sum(p.ripe for p in peppers))

        wanted = View(0.0 if side == 0 else math.pi, 0.0, sum(DISTANCE_RANGE) / 2)
        self.view, waypoints = self.projector.project(None, wanted)
        start = waypoints[-1]
        self.sim.follow(Reference(np.array([0.0, 1.0 / self.sim.rate_hz]), np.array([start, start]), np.zeros((2, 7)),
                                  np.zeros((2, 7))))
        self.views, self.flight_time, self.confirmed = 0, 0.0, (0, 0)
        observation = self._look()
        return observation, self._info(wanted, start, 0.0)

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        if self.sim is None or self._frame is None:
            raise UserError("PepperScanEnv: call reset() before step()")
        try:
            wanted = action_to_view(action, self.plant)
        except (TypeError, ValueError):  # NaN reads as 0, but a wrong shape or a string is no action
            raise UserError(f"PepperScanEnv.step: action {np.shape(action)} is not 3 numbers (azimuth, height, distance)") from None
        before = self.sim.t
        view, waypoints = self.projector.project(self.view, wanted)
        try:
            end = float(self.sim.replan(np.array(waypoints))[-1]) if waypoints else None
        except UserError:  # TOPP-RA found no parameterisation: the robot stays where it is
            end = None
        if end is None:
            self._hover_until(before + STAY)
        else:
            self.view = view
            self._hover_until(end)
            self._settle(waypoints[-1])
        dofs = self.sim.reference[0].copy()
        step_time = self.sim.t - before
        self.flight_time += step_time
        self.views += 1
        confirmed_before = self.confirmed[0]
        observation = self._look()
        reward = float(self.confirmed[0] - confirmed_before - self.time_cost * step_time)
        terminated = self.views >= self.max_views
        truncated = not terminated and self.max_flight_time is not None and self.flight_time >= self.max_flight_time
        return observation, reward, terminated, truncated, self._info(wanted, dofs, step_time)

    def _hover_until(self, t: float) -> None:
        """Fly until `t`, within the plan and the hover after it (sized for a whole episode of views)."""
        while self.sim.t < t - 1e-9 and not self.sim.finished:
            self.sim.step()

    def _settle(self, dofs: np.ndarray) -> None:
        """After the planned motion, hover on until the camera is where it was sent (or MAX_SETTLE has passed)."""
        planned = dofs_to_camera_pose(dofs, self.config.robot.arm)[:3, 3]
        deadline = self.sim.t + MAX_SETTLE
        while (self.sim.t < deadline - 1e-9 and not self.sim.finished
               and np.linalg.norm(self.sim.state.camera_pose[:3, 3] - planned) > SETTLE_TOLERANCE):
            self.sim.step()

    def _look(self) -> dict[str, np.ndarray]:
        """One frame where the camera is now, through perception into the count; the observation."""
        now = self.sim.state.camera_pose
        position, rotation = as_stored(now[:3, 3], now[:3, :3])  # rounded as groundtruth.txt holds poses
        pose = homogeneous(rotation, position)
        index = len(self.perception.frames)
        self._frame = Frame(index, self.sim.t, pose, stored_images(*self.camera.images(index, pose)))
        self.perception.take(self._frame)
        fruit = [f for f in self.perception.counter.counts().fruit
                 if f.plant == self.plant.id and f.support >= self.config.counting.min_views]
        self.confirmed = (len(fruit), sum(f.label == "ripe" for f in fruit))
        counter = np.array([*self.confirmed, index + 1, self.flight_time], dtype=np.float32)
        return {"rgb": self._frame.rgb.copy(), "depth": self._frame.depth.astype(np.float32),
                "camera_pose": pose_vector(pose), "counter": counter}

    def _info(self, wanted: View, dofs: np.ndarray, step_time: float) -> dict[str, Any]:
        return {
            "plant": self.plant.id,
            "scene_seed": self.sim.config.seed,
            "true_fruit": self.truth[0],
            "true_ripe": self.truth[1],
            "confirmed": self.confirmed[0],
            "confirmed_ripe": self.confirmed[1],
            "requested_view": wanted.array(),
            "view": self.view.array(),
            "projected": wanted != self.view,
            "dofs": np.array(dofs, dtype=np.float64),
            "flight_time": float(step_time),
        }

    def _scene_dir(self, config: Config) -> Path:
        """The directory of this scene's files: made by the Simulation unless it is there; the oldest go first."""
        seed = config.seed
        directory = self.run_dir / f"scene-{seed}"
        self._scenes.pop(seed, None)
        self._scenes[seed] = directory
        while self._owned and len(self._scenes) > SCENES_KEPT:
            _, old = self._scenes.popitem(last=False)
            shutil.rmtree(old, ignore_errors=True)
        return directory

    # Output -----------------------------------------------------------------------------------------------------------

    def render(self) -> np.ndarray | None:
        """The last frame's RGB (render_mode "rgb_array"); None before the first reset or without a render mode."""
        if self.render_mode != "rgb_array" or self._frame is None:
            return None
        return self._frame.rgb.copy()

    def close(self) -> None:
        """Closes the simulation and the renderer; removes the temporary directory (a `run_dir` given is kept)."""
        if self._closed:
            return
        self._closed = True
        if self.sim is not None:
            self.sim.close()
            self.sim = None
        if self.camera is not None:
            self.camera.close()
            self.camera = None
        if self._remove is not None:
            self._remove()
