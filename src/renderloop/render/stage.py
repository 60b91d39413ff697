"""`renderloop render DIR`: RGB, depth and instance masks at every camera pose of groundtruth.txt.

`render.json` records what the frames in the directory were rendered from (poses,
scene, camera, renderer settings, backend). A render that finds the same record
resumes, skipping finished frames; one that finds another record starts over,
removing only the frames and lists renderloop wrote, so frames of two different
inputs never mix and nothing else in the directory is touched.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import numpy as np

from renderloop.config import BouncesConfig, Config, RasterConfig, SensorConfig
from renderloop.errors import UserError
from renderloop.io import ownership
from renderloop.render.camera import Intrinsics, write_camera_info
from renderloop.render.contact_sheet import draw_contact_sheet
from renderloop.render.executor import blurs_motion, render_frames
from renderloop.render.frames import frame_done, streams_of, write_frame
from renderloop.render.motion import FlownStates, frames_motion
from renderloop.rundir import files, names
from renderloop.rundir.models import RenderRecord
from renderloop.rundir.stage import Job, Stage
from renderloop.scene.model import read_scene

NEEDS = (names.CONFIG, names.SCENE, names.POSES)
# Bytes a frame may take on disk at most per pixel: 8-bit RGB, then 16-bit depth, mask and sensor depth, as if
# PNG compressed nothing. The estimate is an upper bound, so a run it admits never fills the disk halfway.
BYTES_PER_PIXEL = {names.RGB: 3, names.DEPTH: 2, names.MASKS: 2, names.DEPTH_SENSOR: 2, names.RGB_SENSOR: 3}


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def render_record(run_dir: Path, config: Config, poses: np.ndarray) -> RenderRecord:
    return RenderRecord(
        backend=config.renderer.backend,
        frames=len(poses),
        poses_sha256=_sha256(np.ascontiguousarray(poses).tobytes()),
        scene_sha256=_sha256((run_dir / names.SCENE).read_bytes()),
        seed=config.seed,
        camera=config.camera.model_dump(mode="json"),
        # the thread count and the device say how fast frames come, not what they hold (threads kept at 0 and the
        # device left out, so older records still match)
        renderer={**config.renderer.model_dump(mode="json", exclude={"backend", "device"}), "threads": 0},
    )


def _recorded(run_dir: Path) -> RenderRecord | None:
    recorded = files.read_render_record(run_dir)
    if recorded is None:
        return None
    # a record from before the bounces or the raster look were configurable: its frames had today's defaults, then
    # hard-coded
    missing = {name: section().model_dump(mode="json") for name, section in (("bounces", BouncesConfig), ("raster", RasterConfig))
               if name not in recorded.renderer}
    if missing:
        recorded = recorded.model_copy(update={"renderer": {**missing, **recorded.renderer}})
    if "sensor" not in recorded.camera:  # from before the colour sensor: it was off
        recorded = recorded.model_copy(update={"camera": {**recorded.camera, "sensor": SensorConfig().model_dump(mode="json")}})
    sensor = recorded.camera["sensor"]
    if "exposure_time" not in sensor and not (sensor.get("enabled") and recorded.backend == "cycles"):
        # from before motion blur, which would not have changed its frames (sensor off, or raster): today's default
        sensor = {**sensor, "exposure_time": list(SensorConfig().exposure_time)}
        recorded = recorded.model_copy(update={"camera": {**recorded.camera, "sensor": sensor}})
    return recorded


def _same_record(run_dir: Path, config: Config) -> bool:
    return _recorded(run_dir) == render_record(run_dir, config, files.read_poses(run_dir)[1])


def check_disk(run_dir: Path, config: Config, frames: int) -> None:
    """Refuse, before the first frame, a render whose frames cannot fit on the disk."""
    need = frames * config.camera.width * config.camera.height * sum(BYTES_PER_PIXEL[s] for s in streams_of(config))
    free = shutil.disk_usage(run_dir).free
    if need > free:
        raise UserError(f"{run_dir}: {frames} frames of {config.camera.width}x{config.camera.height} need up to "
                        f"{need / 1e9:.1f} GB but the disk has {free / 1e9:.1f} GB free; lower camera.rate_hz or the image size")


def _render(run_dir: Path, config: Config, job: Job) -> None:
    times, poses = files.read_poses(run_dir)
    record = render_record(run_dir, config, poses)
    if job.force or _recorded(run_dir) != record:
        clear_frames(run_dir)
        files.write_model(run_dir / names.RENDER_RECORD, record)

    streams = streams_of(config)
    todo = [i for i in range(len(poses)) if not frame_done(run_dir, i, streams)]
    done = len(poses) - len(todo)
    if job.progress:
        job.progress(done, len(poses))
    if todo:
        check_disk(run_dir, config, len(todo))
        scene = read_scene(run_dir)
        motion = None
        if blurs_motion(config):  # the camera's motion while each frame's shutter is open, as it was flown
            states = FlownStates.of_flight(files.read_flight(run_dir))
            motion = frames_motion(states, config.robot.arm, times, poses, config.camera.sensor, config.seed)
        for batch in render_frames(config, scene, poses, todo, job.executor, motion):
            for index, frame_files, _ in batch:
                write_frame(run_dir, index, frame_files)
            done += len(batch)
            if job.progress:
                job.progress(done, len(poses))

    finish_render(run_dir, config, times)


def clear_frames(run_dir: Path) -> None:
    """Remove the frames and lists renderloop rendered here before, and nothing else."""
    ownership.remove_recorded(run_dir, (*names.FRAME_DIRS, *map(names.frames_index, names.FRAME_DIRS), *names.OUTPUTS["render"]))


def finish_render(run_dir: Path, config: Config, times: np.ndarray) -> None:
    """With every frame written: the camera's intrinsics, the TUM lists of each stream and the contact sheet."""
    write_camera_info(run_dir, Intrinsics.from_config(config.camera))
    for stream in streams_of(config):
        if stream != names.MASKS:  # the TUM lists name images; masks are ours alone
            files.write_frames_index(run_dir, stream, times)
    draw_contact_sheet(run_dir, len(times), run_dir / names.CONTACT_SHEET)


STAGE = Stage("render", needs=NEEDS, work=_render, current=_same_record)
run_render = STAGE.run


def with_backend(config: Config, backend: str | None, source: str | None = None) -> Config:
    """The config with another renderer backend (`renderloop render --backend`, `Simulation.add_camera`, the gym
    environment; the render record says which made the frames), validated as a config file is: the config model holds
    the backends there are, and an unknown one is its one line, after `source` (default: `unknown backend '...'`)."""
    if backend is None:
        return config
    return config.override({"renderer": {"backend": backend}}, source or f"unknown backend {backend!r}")
