"""`renderloop run --online`: fly, render and detect at once, the camera in the loop.

The planned scan is flown in a `Simulation`; the camera asks for a frame at each of its
instants and the physics goes on stepping while the frame renders; perception takes each
frame as it arrives, in frame order, and feeds the online counter. What comes out is the
run directory of the batch stages fly, render and detect, file for file (the same flight,
the same frames, the same detections), so `count`, `report`, `export` and `eval` read it
unchanged and count what the batch pipeline counts.
"""

from __future__ import annotations

from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from renderloop.config import Config
from renderloop.counting.online import OnlineCounter
from renderloop.loop.mission import AdaptiveMission
from renderloop.loop.sensors import Frame
from renderloop.loop.simulation import Simulation
from renderloop.perception.detector import Detector
from renderloop.perception.fruit_points import find_fruit
from renderloop.perception.stage import write_detections
from renderloop.render.camera import Intrinsics
from renderloop.render.frames import write_frame
from renderloop.render.stage import clear_frames, finish_render, render_record
from renderloop.rundir import files, names
from renderloop.rundir.models import Detection, DetectionFrame
from renderloop.rundir.stage import Job, Stage
from renderloop.sim.stage import NEEDS as FLY_NEEDS
from renderloop.sim.stage import write_flight


MAX_PERCEIVING = 8  # frames waiting for the perception thread before `submit` waits for the oldest


class OnlinePerception:
    """The detector and the fruit points on each frame in frame order, feeding an online counter.

    `take` perceives a frame at once. `submit` and `collect` perceive frames on a thread of their own while the
    caller goes on stepping and rendering (ONNX Runtime, with one thread of its own, and numpy's array work run
    without the GIL): frames are perceived in the order they are submitted, and `collect` adds the finished ones to
    the counter in that order, on the caller's thread, so the counter reads the same whenever the thread finishes.
    A decision reads the counter after `collect(wait=True)`. ONNX Runtime gives the same boxes on one thread as on
    several (tests/test_loop.py compares the online run's detections.json with the batch stage's)."""

    def __init__(self, config: Config, counter: OnlineCounter | None, thread: bool = False) -> None:
        self.detector, self.settings = Detector(config.detector.model, threads=1 if thread else 0), config.detector
        self.intrinsics = Intrinsics.from_config(config.camera)
        self.counter = counter
        self.frames: list[DetectionFrame] = []
        self._thread = ThreadPoolExecutor(1) if thread else None
        self._pending: deque[tuple[Frame, Future]] = deque()

    def _found(self, frame: Frame) -> list[Detection]:
        return find_fruit(self.detector, frame.rgb, frame.depth, frame.pose, self.settings, self.intrinsics)

    def _add(self, frame: Frame, detections: list[Detection]) -> DetectionFrame:
        found = DetectionFrame(index=frame.index, timestamp=round(float(frame.timestamp), 6),
                               image=names.frame_file(frame.colour_stream, frame.index), detections=detections)
        self.frames.append(found)
        self.counter.add(found, frame.pose[:3, 3])
        return found

    def take(self, frame: Frame) -> DetectionFrame:
        """Perceive `frame` now (after the frames submitted before it)."""
        self.collect(wait=True)
        return self._add(frame, self._found(frame))

    def submit(self, frame: Frame) -> None:
        """Perceive `frame` on the perception thread (at once without one); `collect` adds it to the counter. With
        MAX_PERCEIVING frames waiting already, the oldest is waited for: a frame held costs 3 MB at 640x480."""
        if self._thread is None:
            self._add(frame, self._found(frame))
            return
        while len(self._pending) >= MAX_PERCEIVING:
            self._add(*self._next())
        self._pending.append((frame, self._thread.submit(self._found, frame)))

    def _next(self) -> tuple[Frame, list[Detection]]:
        frame, job = self._pending.popleft()
        return frame, job.result()

    def collect(self, wait: bool) -> None:
        """Add the submitted frames perceived so far (with `wait`, all of them) to the counter, in frame order."""
        while self._pending and (wait or self._pending[0][1].done()):
            self._add(*self._next())

    def close(self) -> None:
        if self._thread is not None:
            self._thread.shutdown(cancel_futures=True)

    def __enter__(self) -> OnlinePerception:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _fly_in_loop(run_dir: Path, config: Config, job: Job) -> None:
    """The scan flown with the camera in the loop; with `mission.kind: adaptive`, steered by `AdaptiveMission`."""
    adaptive = config.mission.kind == "adaptive"
    clear_frames(run_dir)  # the frames of an earlier or interrupted run: these are rendered again as the robot flies
    with ExitStack() as stack:
        sim = stack.enter_context(Simulation(config, run_dir))
        sim.follow(sim.scan_trajectory())
        rate = config.mission.adaptive.first_pass_rate_hz if adaptive else None
        executor = job.executor
        camera = sim.add_camera(rate_hz=rate, workers=executor.workers, executor=executor.kind, address=executor.address,
                                encode=True)
        counter = OnlineCounter(sim.scene, config.counting, config.seed)
        perception = stack.enter_context(OnlinePerception(config, counter, thread=True))
        mission = AdaptiveMission(sim, camera, counter, config) if adaptive else None
        written = 0

        def take_ready(wait: bool) -> None:
            """Frames are taken in order; without `wait`, only as far as they have arrived (the physics never waits)."""
            nonlocal written
            while written < len(camera) and (wait or camera.ready(written)):
                frame = camera.frame(written)
                write_frame(run_dir, frame.index, frame.files)
                perception.submit(frame)
                if mission is not None:
                    mission.take(frame)
                camera.release(frame.index)  # the perception thread holds the frame until it is done with it
                written += 1
                if job.progress:
                    job.progress(written, max(len(camera), 1))
            perception.collect(wait)

        while not sim.finished:
            sim.step()
            if mission is not None and mission.due():
                take_ready(wait=True)  # a decision reads every frame taken before it, whenever they render and are perceived
                mission.decide()
            elif not sim.tick % 10:  # a look every 10 ticks is plenty for frames that come at 5 Hz at most
                take_ready(wait=False)
        take_ready(wait=True)

        log = sim.log()
        frames = np.searchsorted(log.t, np.array(camera.timestamps) - 1e-9)
        poses = np.array(camera.poses)
        record = mission.record(camera.timestamps, sim.end) if mission is not None else None
    # the files of the batch stages, in their order, from the same flight and frames
    write_flight(run_dir, config, log, frames)
    files.write_model(run_dir / names.RENDER_RECORD, render_record(run_dir, config, poses))
    finish_render(run_dir, config, log.t[frames])
    depth_dir = names.DEPTH_SENSOR if config.renderer.depth_noise.enabled else names.DEPTH
    write_detections(run_dir, perception.detector, config.detector, depth_dir, perception.frames)
    if record is not None:
        files.write_model(run_dir / names.MISSION, record)


STAGE = Stage("online", needs=FLY_NEEDS, work=_fly_in_loop, covers=("fly", "render", "detect"))
run_online = STAGE.run
ADAPTIVE_STAGE = Stage("adaptive", needs=FLY_NEEDS, work=_fly_in_loop, covers=("fly", "render", "detect", "mission"))
