"""Perception in the loop: the detector and the fruit points on each frame as the camera delivers it, in frame order,
feeding an online counter; the online stage and the Gymnasium environment share it."""

from __future__ import annotations

from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor

from renderloop.config import Config
from renderloop.counting.online import OnlineCounter
from renderloop.loop.sensors import Frame
from renderloop.perception.detector import Detector
from renderloop.perception.fruit_points import detect_frame
from renderloop.render.camera import Intrinsics
from renderloop.rundir import names
from renderloop.rundir.models import DetectionFrame

MAX_PERCEIVING = 8  # frames waiting for the perception thread before `submit` waits for the oldest


class OnlinePerception:
    """The detector and the fruit points on each frame in frame order, feeding an online counter.

    `take` perceives a frame at once. `submit` and `collect` perceive frames on a thread of their own while the
    caller goes on stepping and rendering (ONNX Runtime, whose own threads sleep when idle, and numpy's array work
    run without the GIL): frames are perceived in the order they are submitted, and `collect` adds the finished ones to
    the counter in that order, on the caller's thread, so the counter reads the same whenever the thread finishes.
    A decision reads the counter after `collect(wait=True)`. ONNX Runtime gives the same boxes on one thread as on
    several (tests/test_loop.py compares the online run's detections.json with the batch stage's)."""

    def __init__(self, config: Config, counter: OnlineCounter | None, thread: bool = False) -> None:
        self.detector, self.settings = Detector(config.detector.model), config.detector
        self.intrinsics = Intrinsics.from_config(config.camera)
        self.counter = counter
        self.frames: list[DetectionFrame] = []
        self._thread = ThreadPoolExecutor(1) if thread else None
        self._pending: deque[tuple[Frame, Future[DetectionFrame]]] = deque()

    def _found(self, frame: Frame) -> DetectionFrame:
        return detect_frame(self.detector, frame.index, frame.timestamp, names.frame_file(frame.colour_stream, frame.index),
                            frame.rgb, frame.depth, frame.pose, self.settings, self.intrinsics)

    def _add(self, frame: Frame, found: DetectionFrame) -> DetectionFrame:
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

    def _next(self) -> tuple[Frame, DetectionFrame]:
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
