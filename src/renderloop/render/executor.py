"""Frames rendered by workers: one renderer each, built once, in this process, on local processes or as Ray actors.

A worker holds one renderer (one Blender scene, or one MuJoCo GL context), built once,
and renders chunks of frame indices; it returns encoded PNGs instead of writing them,
so the driver is the only writer (atomic renames, one progress count) and a Ray
worker on another machine needs no shared file system: it receives the config, the
scene and the poses, not paths. Where the workers run is `renderloop.parallel`'s.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np

from renderloop.config import Config
from renderloop.parallel import Executor, Workers
from renderloop.render.camera import Intrinsics
from renderloop.render.depth_noise import sensor_depth
from renderloop.render.frame import RenderedFrame
from renderloop.render.frames import encode_frame
from renderloop.render.sensor import sensor_rgb
from renderloop.scene.model import Scene

DEPTH_NOISE_STREAM, COLOUR_SENSOR_STREAM = 0xD3, 0x5E  # the named random streams of the two sensor models
CHUNK = 4  # frames per task: large enough to amortise a task, small enough to balance 2 workers

Rendered = list[tuple[int, dict[str, bytes], dict[str, float]]]


def make_renderer(config: Config, scene: Scene, viewpoints: np.ndarray | None = None):
    """The renderer of the config's backend (the config model holds which there are); `viewpoints`, (N, 3): where
    its camera will be, so that it builds only what can be seen from there (None: the whole scene)."""
    intrinsics = Intrinsics.from_config(config.camera)
    if config.renderer.backend == "raster":
        from renderloop.render.raster import RasterRenderer

        return RasterRenderer(scene, config, intrinsics, viewpoints)
    from renderloop.render.cycles import CyclesRenderer

    return CyclesRenderer(scene, config, intrinsics, viewpoints)


def blurs_motion(config: Config) -> bool:
    """Whether frames need the camera's motion during the exposure: the colour sensor's stream, rendered by Cycles.
    The raster backend renders one instant (MuJoCo's OpenGL has no shutter), so its rgb_sensor/ has no motion blur."""
    return config.camera.sensor.enabled and config.camera.sensor.exposure_time[1] > 0 and config.renderer.backend == "cycles"


class FrameWorker:
    """Renders frames of one run; everything it needs travels with it (picklable)."""

    def __init__(self, config: Config, scene: Scene, poses: np.ndarray | None = None, motion: np.ndarray | None = None):
        # poses (N, 4, 4), motion (N, 2, 4, 4): a batch's, or None for frames asked for one by one
        self.config, self.poses, self.motion = config, poses, motion
        # with the poses known, the renderer builds what the camera sees from them (and from the shutter's ends)
        viewpoints = None if poses is None else np.concatenate(
            [np.asarray(poses)[:, :3, 3], *([] if motion is None else [np.asarray(motion)[:, :, :3, 3].reshape(-1, 3)])])
        self.renderer = make_renderer(config, scene, viewpoints)

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


def render_frames(config: Config, scene: Scene, poses: np.ndarray, indices: list[int], executor: Executor,
                  motion: np.ndarray | None = None) -> Iterator[Rendered]:
    """Frames `indices` of a run, a chunk at a time as the executor's workers finish them (in this process for one
    local worker); `motion`, (N, 2, 4, 4): the poses at each frame's shutter opening and closing, or None."""
    with Workers(executor, FrameWorker, executor.share_cores(config), scene, poses, motion) as workers:
        yield from workers.as_completed("render", _chunks(indices))
