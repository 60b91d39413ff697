"""`renderloop render DIR`: RGB, depth and instance masks at every camera pose of groundtruth.txt.

`render.json` records what the frames in the directory were rendered from (poses,
scene, camera, renderer settings, backend). A render that finds the same record
resumes, skipping finished frames; one that finds another record starts over,
removing only the frames and lists renderloop wrote, so frames of two different
inputs never mix and nothing else in the directory is touched.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.io import ownership
from renderloop.io.disk import free_bytes
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
    """What frames rendered now in `run_dir` would be made from: its scene file, these poses and the config's camera
    and renderer."""
    return RenderRecord(
        backend=config.renderer.backend,
        frames=len(poses),
        poses_sha256=_sha256(np.ascontiguousarray(poses).tobytes()),
        scene_sha256=_sha256((run_dir / names.SCENE).read_bytes()),
        seed=config.seed,
        camera=config.camera.model_dump(mode="json"),
        # the thread count and the device say how fast frames come, not what they hold
        renderer={**config.renderer.model_dump(mode="json", exclude={"backend", "device"}), "threads": 0},
    )


def _same_record(run_dir: Path, config: Config) -> bool:
    return files.read_render_record(run_dir) == render_record(run_dir, config, files.read_poses(run_dir)[1])


def check_disk(run_dir: Path, config: Config, frames: int) -> None:
    """Refuse, before the first frame, a render whose frames cannot fit on the disk."""
    need = frames * config.camera.width * config.camera.height * sum(BYTES_PER_PIXEL[s] for s in streams_of(config))
    free = free_bytes(run_dir)
    if need > free:
        raise UserError(f"{run_dir}: {frames} frames of {config.camera.width}x{config.camera.height} need up to "
                        f"{need / 1e9:.1f} GB but the disk has {free / 1e9:.1f} GB free; lower camera.rate_hz or the image size")


def _render(run_dir: Path, config: Config, job: Job) -> None:
    times, poses = files.read_poses(run_dir)
    record = render_record(run_dir, config, poses)
    if job.force or files.read_render_record(run_dir) != record:
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
