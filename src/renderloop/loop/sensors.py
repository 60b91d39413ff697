"""The camera in the loop: it fires at its instants while the robot flies, and frames arrive as they are rendered.

A frame is asked for at the camera's instant and rendered by `renderloop.render.executor.FrameWorker`,
the same code and the same per-frame noise seed as `renderloop render`, so a frame rendered in the
loop is byte for byte the frame a batch render of that pose gives. Raster frames are rendered at
once in this process; Cycles frames in worker processes (or Ray actors), so the physics keeps
stepping while they render and waits only when a consumer asks for a frame that is not there yet.
Results are keyed by frame index, so nothing depends on which worker finished first.

A Cycles frame with the colour sensor on is blurred by the camera's motion while its shutter
is open (`renderloop.render.motion`), from t - e/2 to t + e/2: the camera keeps the flown state
of every tick, rounded as flight.csv stores it, and asks for the frame at the first tick at or
after t + e/2, when the motion it was exposed over has been flown; until then it is not ready.
"""

from __future__ import annotations

import io
import math
from bisect import bisect_left, insort
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from PIL import Image

from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.io.tum import as_stored
from renderloop.parallel import Executor, Pending, Workers
from renderloop.render.executor import FrameWorker, blurs_motion
from renderloop.render.frames import decode_depth, encode_images, stored_images
from renderloop.render.motion import FlownStates, exposure_poses, exposure_time, stored
from renderloop.robot.kinematics import homogeneous
from renderloop.rundir import names
from renderloop.scene.model import Scene
from renderloop.sim.flight import Snapshot


def _decode(png: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(png)) as image:
        return np.array(image)


@dataclass(frozen=True)
class Frame:
    """One camera frame: when, where from (T_world_optical), and its images as the run directory stores them."""

    index: int
    timestamp: float
    pose: np.ndarray
    images: dict[str, np.ndarray] = field(default_factory=dict, repr=False)  # by stream, not encoded (frames of this process)
    encoded: dict[str, bytes] | None = field(default=None, repr=False)  # PNG bytes by stream, where they were made already

    @cached_property
    def files(self) -> dict[str, bytes]:
        """PNG bytes by stream (rgb, depth, masks and the sensor streams), as the run directory stores them: compressed
        now if the camera did not compress them ahead (`Simulation.add_camera(encode=...)`)."""
        return self.encoded if self.encoded is not None else encode_images(self.images)

    def _stored(self, stream: str) -> np.ndarray:
        """A stream as its file holds it: the image itself when this process rendered it, else its PNG decoded."""
        return self.images[stream] if stream in self.images else _decode(self.files[stream])

    @property
    def _streams(self) -> dict:
        return self.images or self.files

    @property
    def colour_stream(self) -> str:
        """The colour the camera delivers: the sensor stream when the camera has one."""
        return names.RGB_SENSOR if names.RGB_SENSOR in self._streams else names.RGB

    @property
    def depth_stream(self) -> str:
        return names.DEPTH_SENSOR if names.DEPTH_SENSOR in self._streams else names.DEPTH

    @cached_property
    def rgb(self) -> np.ndarray:
        """Colour as the camera delivers it: the sensor stream when the camera has one."""
        return self._stored(self.colour_stream)

    @cached_property
    def depth(self) -> np.ndarray:
        """Planar depth, m (0 = no return): the sensor stream when the camera has one, as a real camera gives."""
        return decode_depth(self._stored(self.depth_stream))

    @cached_property
    def ideal_rgb(self) -> np.ndarray:
        return self._stored(names.RGB)

    @cached_property
    def ideal_depth(self) -> np.ndarray:
        return decode_depth(self._stored(names.DEPTH))

    @cached_property
    def mask(self) -> np.ndarray:
        """Pepper instance ids (0 = not a pepper): the simulator's truth."""
        return self._stored(names.MASKS)


MAX_ENCODING = 16  # raster frames waiting for their PNGs (3 MB each at 640x480) before the camera waits for the oldest


class _Renderers:
    """Where frames are rendered: this process (raster), local processes, or Ray actors."""

    def __init__(self, config: Config, scene: Scene, executor: Executor, encode: bool):
        self.pending: dict[int, Future | Pending] = {}  # each frame's (index, files or None, timings) to come
        self.images: dict[int, dict[str, np.ndarray]] = {}  # the frames this process rendered, not encoded
        self._close: list[Callable[[], None]] = []
        if executor.kind == "local" and executor.workers <= 1 and config.renderer.backend == "raster":
            self.local = FrameWorker(config, scene)
            self._close.append(self.local.close)
            if encode:  # PNG compression, a third of a raster frame's time, on a thread of its own: zlib works without the GIL
                self.encoder, self.encoding = ThreadPoolExecutor(1), deque()
                self._close.append(lambda: self.encoder.shutdown(cancel_futures=True))
        else:  # off this process, even one worker: the physics keeps stepping while frames render
            self.workers = Workers(executor, FrameWorker, executor.share_cores(config), scene, background=True)
            self._close.append(self.workers.close)

    def submit(self, index: int, pose: np.ndarray, motion: np.ndarray | None = None) -> None:
        if hasattr(self, "local"):
            frame, depth, rgb = self.local.images(index, pose, motion)
            images = self.images[index] = stored_images(frame, depth, rgb)
            for image in images.values():  # read by the encoder and the perception thread at once: nobody writes them
                image.flags.writeable = False
            if not hasattr(self, "encoder"):
                self.pending[index] = Pending.of((index, None, frame.timings))  # files encoded if they are asked for
                return
            while len(self.encoding) >= MAX_ENCODING:  # a bounded queue: frames held waiting cost 3 MB each
                self.encoding.popleft().result()
            self.pending[index] = job = self.encoder.submit(lambda: (index, encode_images(images), frame.timings))
            self.encoding.append(job)
            while self.encoding and self.encoding[0].done():
                self.encoding.popleft()
        else:
            self.pending[index] = self.workers.submit("render_pose", index, pose, motion)

    def ready(self, index: int) -> bool:
        return self.pending[index].done()

    def result(self, index: int) -> dict[str, bytes] | None:
        return self.pending[index].result()[1]

    def forget(self, index: int) -> None:
        self.pending.pop(index, None)
        self.images.pop(index, None)

    def close(self) -> None:
        while self._close:
            self._close.pop()()


class Camera:
    """The RGB-D camera on the arm's tip: a frame at every instant k / rate_hz of the planned motion, and at any
    instant a mission asks for (`trigger`); a mission can also hold the periodic frames back (`pause`)."""

    def __init__(self, config: Config, scene: Scene, control_rate_hz: float, rate_hz: float, executor: Executor,
                 encode: bool = False) -> None:
        if not 0 < rate_hz <= control_rate_hz:
            raise UserError(f"camera rate {rate_hz} Hz: the control loop at {control_rate_hz} Hz cannot serve it "
                            f"(0 < rate <= {control_rate_hz})")
        self.config, self.rate_hz = config, rate_hz
        self.blurs = blurs_motion(config)
        self.renderers = _Renderers(config, scene, executor, encode)
        self.restart()

    def restart(self) -> None:
        """Forget the frames asked for so far (a new trajectory starts a new recording)."""
        self.timestamps: list[float] = []
        self.poses: list[np.ndarray] = []
        self._periodic = 0  # k of the next periodic instant k / rate_hz
        self._triggers: list[float] = []  # instants asked for, in order
        self._frames: dict[int, Frame] = {}
        self._released: set[int] = set()
        self._flown_t: list[float] = []  # the flown state of every tick, for the motion during exposures
        self._flown: list[list[float]] = []
        self._exposing: dict[int, tuple[float, float]] = {}  # frames whose shutter is still open: (t, exposure)
        self.shutters: dict[int, np.ndarray] = {}  # a blurred frame's poses at its shutter's opening and closing
        self.renderers.pending.clear()
        self.renderers.images.clear()

    def observe(self, now: float, snapshot: Snapshot, end: float) -> None:
        """Called at every control tick: ask for a frame when one of the camera's instants has come."""
        if self.blurs:  # as flight.csv will hold it, so the motion is the batch render's to the bit
            row = stored([now, *snapshot.position, *snapshot.quaternion, *snapshot.joints])
            self._flown_t.append(row[0])
            self._flown.append(row)
        periodic = self._periodic / self.rate_hz
        due_periodic = periodic <= end + 1e-9 and now >= periodic - 1e-9
        due_trigger = bool(self._triggers) and now >= self._triggers[0] - 1e-9
        if due_periodic or due_trigger:
            if due_periodic:
                self._periodic += 1
            while self._triggers and now >= self._triggers[0] - 1e-9:
                self._triggers.pop(0)
            index = len(self.timestamps)
            position, rotation = as_stored(snapshot.camera_position, snapshot.camera_rotation)
            pose = homogeneous(rotation, position)  # as groundtruth.txt will hold it, so batch renders see the same pose
            self.timestamps.append(now)
            self.poses.append(pose)
            if self.blurs:
                self._exposing[index] = (stored([now])[0], exposure_time(self.config.camera.sensor, self.config.seed, index))
            else:
                self.renderers.submit(index, pose)
        for index, (t, exposure) in list(self._exposing.items()):
            if self._flown_t[-1] >= t + exposure / 2:  # the tick the batch render interpolates the shutter's close to
                self._submit_exposed(index)

    def trigger(self, t: float) -> None:
        """A frame at the first control tick at or after simulation time `t` (one frame serves instants that meet)."""
        insort(self._triggers, float(t))

    def pause(self, until: float) -> None:
        """No periodic frame before simulation time `until`; the periodic instants k / rate_hz resume after it."""
        self._periodic = max(self._periodic, math.ceil(until * self.rate_hz - 1e-9))

    def _submit_exposed(self, index: int) -> None:
        """Ask for a frame whose exposure has been flown (or, asked for before, the flight so far: the camera holds
        its last state, as a batch render of a flight that ended here would)."""
        t, exposure = self._exposing.pop(index)
        first = max(bisect_left(self._flown_t, t - exposure / 2) - 1, 0)  # the ticks the batch render interpolates
        states = FlownStates.of_rows(self._flown[first:])
        self.shutters[index] = exposure_poses(states, self.config.robot.arm, t, self.poses[index], exposure)
        self.renderers.submit(index, self.poses[index], self.shutters[index])

    def __len__(self) -> int:
        """Frames asked for so far."""
        return len(self.timestamps)

    def ready(self, index: int) -> bool:
        return index in self._frames or (index not in self._exposing and self.renderers.ready(index))

    def frame(self, index: int) -> Frame:
        """Frame `index`, waiting for its render if it is not there yet."""
        if index not in self._frames:
            if not 0 <= index < len(self.timestamps):
                raise UserError(f"camera frame {index}: only {len(self.timestamps)} frames were asked for")
            if index in self._released:
                raise UserError(f"camera frame {index} was released")
            if index in self._exposing:
                self._submit_exposed(index)
            self._frames[index] = Frame(index, self.timestamps[index], self.poses[index],
                                        self.renderers.images.get(index, {}), self.renderers.result(index))
        return self._frames[index]

    def release(self, index: int) -> None:
        """Forget frame `index`'s images once what was needed is taken from them: a 640x480 frame holds about 3 MB
        (its files, and its images once read), so a paper scan at 5 Hz kept whole would hold 10 GB."""
        self._frames.pop(index, None)
        self.renderers.forget(index)
        self._released.add(index)

    def frames_until(self, t: float) -> list[Frame]:
        """Every frame taken at or before simulation time `t` and not released, in order; waits only for those not
        rendered yet."""
        return [self.frame(i) for i, stamp in enumerate(self.timestamps) if stamp <= t + 1e-9 and i not in self._released]

    def close(self) -> None:
        self.renderers.close()
