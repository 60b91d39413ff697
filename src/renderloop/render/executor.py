"""Where frames are rendered: in this process, on N local processes, or as Ray actors.

A worker holds one renderer (one Blender scene, or one MuJoCo GL context), built once,
and renders chunks of frame indices; it returns encoded PNGs instead of writing them,
so the driver is the only writer (atomic renames, one progress count) and a Ray
worker on another machine needs no shared file system: it receives the config, the
scene and the poses, not paths.
"""

from __future__ import annotations

import os
import socket
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context

import numpy as np

from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.render.camera import Intrinsics
from renderloop.render.depth_noise import sensor_depth
from renderloop.render.frame import RenderedFrame
from renderloop.render.frames import encode_frame
from renderloop.render.sensor import sensor_rgb
from renderloop.scene.model import Scene

BACKENDS = ("cycles", "raster")
DEPTH_NOISE_STREAM, COLOUR_SENSOR_STREAM = 0xD3, 0x5E  # the named random streams of the two sensor models
CHUNK = 4  # frames per task: large enough to amortise a task, small enough to balance 2 workers

Rendered = list[tuple[int, dict[str, bytes], dict[str, float]]]


def make_renderer(backend: str, scene: Scene, config: Config, intrinsics: Intrinsics):
    if backend == "raster":
        from renderloop.render.raster import RasterRenderer

        return RasterRenderer(scene, config, intrinsics)
    if backend == "cycles":
        from renderloop.render.cycles import CyclesRenderer

        return CyclesRenderer(scene, config, intrinsics)
    raise UserError(f"unknown backend {backend!r} (choose from: {', '.join(BACKENDS)})")


def blurs_motion(config: Config, backend: str) -> bool:
    """Whether frames need the camera's motion during the exposure: the colour sensor's stream, rendered by Cycles.
    The raster backend renders one instant (MuJoCo's OpenGL has no shutter), so its rgb_sensor/ has no motion blur."""
    return config.camera.sensor.enabled and config.camera.sensor.exposure_time[1] > 0 and backend == "cycles"


class FrameWorker:
    """Renders frames of one run; everything it needs travels with it (picklable)."""

    def __init__(self, config: Config, scene: Scene, poses: np.ndarray | None, backend: str,
                 motion: np.ndarray | None = None):
        # poses (N, 4, 4), motion (N, 2, 4, 4): a batch's, or None for frames asked for one by one
        self.config, self.poses, self.motion = config, poses, motion
        self.renderer = make_renderer(backend, scene, config, Intrinsics.from_config(config.camera))

    def render_pose(self, index: int, pose: np.ndarray,
                    motion: np.ndarray | None = None) -> tuple[int, dict[str, bytes], dict[str, float]]:
        """Frame `index`, seen from `pose` (T_world_optical), as its files' bytes; `motion`: the poses at the shutter's
        opening and closing (render/motion.py), which the colour sensor's frame is blurred between (Cycles only;
        None: a still camera)."""
        frame, depth, rgb = self.images(index, pose, motion)
        return index, encode_frame(frame, depth, rgb), frame.timings

    def images(self, index: int, pose: np.ndarray,
               motion: np.ndarray | None = None) -> tuple[RenderedFrame, np.ndarray | None, np.ndarray | None]:
        """Frame `index` before encoding: the ideal frame, and the sensor's depth and colour where the config has them."""
        frame = self.renderer.render(pose)
        config, depth, rgb = self.config, None, None
        # each sensor seeded per frame, so a frame does not depend on which worker drew it
        if config.renderer.depth_noise.enabled:
            rng = np.random.default_rng(np.random.SeedSequence([config.seed, DEPTH_NOISE_STREAM, index]))
            depth = sensor_depth(frame.depth, config.renderer.depth_noise, config.camera.clip, rng)
        if config.camera.sensor.enabled:
            colour = frame.rgb
            if motion is not None and hasattr(self.renderer, "render_blurred"):
                start = time.perf_counter()  # a second path-traced render: the ideal frame stays unblurred
                colour = self.renderer.render_blurred(motion[0], motion[1])
                frame.timings["motion_blur"] = time.perf_counter() - start
            rng = np.random.default_rng(np.random.SeedSequence([config.seed, COLOUR_SENSOR_STREAM, index]))
            # the ideal depth for the lens's defocus: blurred depth is not a depth (CyclesRenderer.render_blurred)
            rgb = sensor_rgb(colour, frame.depth, config.camera.sensor, rng)
        return frame, depth, rgb

    def render(self, indices: list[int]) -> Rendered:
        motion = self.motion if self.motion is not None else [None] * len(self.poses)
        return [self.render_pose(index, self.poses[index], motion[index]) for index in indices]

    def close(self) -> None:
        self.renderer.close()


def _chunks(indices: list[int]) -> list[list[int]]:
    return [indices[i : i + CHUNK] for i in range(0, len(indices), CHUNK)]


def threads_per_worker(config: Config, workers: int) -> Config:
    """N renderers on N processes share the cores instead of each taking all of them."""
    if workers <= 1 or config.renderer.threads:
        return config
    threads = max(1, (os.cpu_count() or 1) // workers)
    return config.model_copy(update={"renderer": config.renderer.model_copy(update={"threads": threads})})


_process_worker: FrameWorker | None = None
_start_error: Exception | None = None


def _start_process_worker(config: Config, scene: Scene, poses: np.ndarray, backend: str,
                          motion: np.ndarray | None) -> None:
    global _process_worker, _start_error
    try:
        _process_worker = FrameWorker(config, scene, poses, backend, motion)
    except Exception as error:  # kept for the first task: a failing initializer only tells the driver "BrokenProcessPool"
        _start_error = error


def _render_in_process_worker(indices: list[int]) -> Rendered:
    if _start_error is not None:
        raise _start_error  # e.g. the UserError of `renderer.device: gpu` without a GPU, one line as without workers
    assert _process_worker is not None
    return _process_worker.render(indices)


@contextmanager
def spawn_safely() -> Iterator[None]:
    """What spawned workers take from the parent while they start, held back for the time they start:

    - sys.path: once bpy is imported it holds Blender's scripts/modules, whose inner `bpy` package shadows the real
      one and makes `import bpy` fail in the child;
    - the main script: a spawned child runs it again unless `if __name__ == "__main__":` guards it, so a user's script
      that flies a Cycles camera would start itself in every worker (and hang, the parent writing the worker's scene
      into a pipe nobody reads). The workers run renderloop's own functions and need nothing of it."""
    saved = list(sys.path)
    main = sys.modules.get("__main__")
    held = {name: vars(main)[name] for name in ("__file__", "__spec__") if main is not None and name in vars(main)}
    sys.path[:] = [p for p in saved if not ("scripts" in p and ("bpy" in p or "blender" in p))]
    if held:  # multiprocessing.spawn finds the script by __spec__'s name (python -m) or else by __file__
        vars(main).pop("__file__", None)
        main.__spec__ = None
    try:
        yield
    finally:
        sys.path[:] = saved
        if held:
            vars(main).update(held)


def render_local(config: Config, scene: Scene, poses: np.ndarray, backend: str, indices: list[int], workers: int,
                 motion: np.ndarray | None = None) -> Iterator[Rendered]:
    if workers <= 1:
        worker = FrameWorker(config, scene, poses, backend, motion)
        try:
            for chunk in _chunks(indices):
                yield worker.render(chunk)
        finally:
            worker.close()
        return
    config = threads_per_worker(config, workers)
    # spawn, not fork: neither Blender nor an OpenGL context survives a fork
    with ProcessPoolExecutor(workers, mp_context=get_context("spawn"), initializer=_start_process_worker,
                             initargs=(config, scene, poses, backend, motion)) as pool:
        with spawn_safely():  # the workers start on the first submissions
            futures = [pool.submit(_render_in_process_worker, chunk) for chunk in _chunks(indices)]
        for future in as_completed(futures):
            yield future.result()


def _check_answers(address: str, timeout: float = 3.0) -> None:
    """Ray retries an unanswered address for minutes; a plain TCP connect says no in seconds."""
    if address == "auto":
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        socket.create_connection((host or "127.0.0.1", int(port)), timeout=timeout).close()
    except (OSError, ValueError):
        raise UserError(f"--address {address}: no Ray cluster answers there") from None


@contextmanager
def ray_session(workers: int, address: str | None) -> Iterator[None]:
    """Join the cluster at `address`, or start a local one with `workers` CPUs; a session
    started here is shut down on leaving, one the caller started is left running."""
    import ray

    started_here = not ray.is_initialized()
    if started_here:
        try:
            if address:
                _check_answers(address)
                ray.init(address=address, log_to_driver=False)
            else:
                ray.init(num_cpus=max(workers, 1), include_dashboard=False, log_to_driver=False)
        except UserError:
            raise
        except (ConnectionError, RuntimeError, ValueError) as error:
            raise UserError(f"--address {address}: no Ray cluster answers there ({str(error).splitlines()[0]})") from None
    try:
        yield
    finally:
        if started_here:
            ray.shutdown()


def render_ray(config: Config, scene: Scene, poses: np.ndarray, backend: str, indices: list[int], workers: int, address: str | None,
               motion: np.ndarray | None = None) -> Iterator[Rendered]:
    import ray

    with ray_session(workers, address):
        config = threads_per_worker(config, workers)
        actor = ray.remote(num_cpus=1)(FrameWorker)
        actors = [actor.remote(config, scene, poses, backend, motion) for _ in range(max(workers, 1))]
        pending, chunks = {}, _chunks(indices)
        for worker in actors:  # one chunk in flight per actor; the next goes to whichever finishes first
            if chunks:
                pending[worker.render.remote(chunks.pop(0))] = worker
        while pending:
            [done], _ = ray.wait(list(pending), num_returns=1)
            worker = pending.pop(done)
            if chunks:
                pending[worker.render.remote(chunks.pop(0))] = worker
            yield ray.get(done)
