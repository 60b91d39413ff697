"""`renderloop detect DIR`: 2D pepper detections on every frame and their 3D points in the world.

Writes `detections.json` (`renderloop.rundir.models.Detections`: the detector's settings and,
per frame, boxes in pixels, scores, ripe/unripe labels and the fruit point in the world frame,
null when the box holds too few depth returns). Depth is the sensor stream (noisy, with
dropouts) when the run rendered one, as a real camera would give.

Frames are processed in order and each frame's result is appended to a cache, so a
bad frame stops the stage with the frames before it kept, and the next run goes on
from there. detection_scores.json scores the detections against the masks (the
simulator's truth) and detections.png shows frames with both.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import BaseModel, ValidationError

from renderloop.config import Config, DetectorConfig
from renderloop.errors import UserError
from renderloop.io import ownership
from renderloop.perception.detector import Detector
from renderloop.perception.fruit_points import detect_frame
from renderloop.perception.scoring import score_frames
from renderloop.perception.sheet import draw_detection_sheet
from renderloop.render.camera import Intrinsics, read_camera_info
from renderloop.render.frames import decode_depth, read_png, read_rgb_frame, sensor_depth_dir, sensor_rgb_dir
from renderloop.rundir import files, names
from renderloop.rundir.models import DetectionFrame, Detections
from renderloop.rundir.stage import Job, Stage
from renderloop.scene.model import read_scene

NEEDS = (names.CONFIG, names.SCENE, names.POSES, names.frames_index(names.RGB), names.frames_index(names.DEPTH), names.CAMERA_INFO)


class _CacheLine(BaseModel):
    model: str  # the detector and settings that made the frame
    frame: DetectionFrame


def _read_cache(path: Path, key: str) -> list[DetectionFrame]:
    """Frames already done with these settings; a torn last line (a kill mid-write) ends what can be trusted."""
    frames: list[DetectionFrame] = []
    if not path.is_file():
        return frames
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            entry = _CacheLine.model_validate_json(line)
        except ValidationError:
            break
        if entry.model != key or entry.frame.index != len(frames):
            return []
        frames.append(entry.frame)
    return frames


def _read_frame(detector: Detector, run_dir: Path, index: int, timestamp: float, pose: np.ndarray, depth_dir: str,
                settings: DetectorConfig, intrinsics: Intrinsics) -> DetectionFrame:
    """Frame `index` read from the run, its colour and depth checked against each other and camera_info.yaml, and
    detected."""
    rgb = read_rgb_frame(run_dir, index)
    depth_path = run_dir / names.frame_file(depth_dir, index)
    depth = decode_depth(read_png(depth_path, np.uint16))
    if depth.shape != rgb.shape[:2]:
        raise UserError(f"{depth_path}: depth is {depth.shape[1]}x{depth.shape[0]} but the RGB frame is {rgb.shape[1]}x{rgb.shape[0]}")
    if depth.shape != (intrinsics.height, intrinsics.width):
        raise UserError(f"{depth_path}: {depth.shape[1]}x{depth.shape[0]} does not match {names.CAMERA_INFO}")
    image = names.frame_file(sensor_rgb_dir(run_dir), index)
    return detect_frame(detector, index, timestamp, image, rgb, depth, pose, settings, intrinsics)


def _detect(run_dir: Path, config: Config, job: Job) -> None:
    settings = config.detector
    detector = Detector(settings.model)
    times, poses = files.read_poses(run_dir)
    intrinsics = read_camera_info(run_dir)
    depth_dir = sensor_depth_dir(run_dir)
    cache = run_dir / names.DETECT_CACHE
    key = (f"{detector.path}@{settings.score_threshold}@{','.join(settings.windows)}@{settings.mirror}"
           f"@{settings.max_window_enlargement}@{settings.min_box_px}@{depth_dir}@{sensor_rgb_dir(run_dir)}")
    frames = [] if job.force else _read_cache(cache, key)
    ownership.record(cache)  # appended to as frames finish, not renamed into place: recorded here
    with open(cache, "w", encoding="utf-8") as out:  # rewritten from what was valid, then appended to
        out.writelines(_CacheLine(model=key, frame=frame).model_dump_json() + "\n" for frame in frames)
        out.flush()
        for index in range(len(frames), len(poses)):
            if job.progress:
                job.progress(index, len(poses))
            frame = _read_frame(detector, run_dir, index, times[index], poses[index], depth_dir, settings, intrinsics)
            out.write(_CacheLine(model=key, frame=frame).model_dump_json() + "\n")
            out.flush()
            frames.append(frame)
    if job.progress:
        job.progress(len(poses), len(poses))
    write_detections(run_dir, detector, settings, depth_dir, frames)
    cache.unlink(missing_ok=True)


def write_detections(run_dir: Path, detector: Detector, settings: DetectorConfig, depth_dir: str,
                     frames: list[DetectionFrame]) -> None:
    """detections.json, its scores against the masks and the sheet of frames with both."""
    files.write_model(run_dir / names.DETECTIONS, Detections(
        model=str(detector.path), score_threshold=settings.score_threshold, windows=list(settings.windows),
        mirror=settings.mirror, max_window_enlargement=settings.max_window_enlargement, depth=depth_dir, frames=frames))
    masks = (read_png(run_dir / names.frame_file(names.MASKS, frame.index), np.uint16) for frame in frames)
    files.write_model(run_dir / names.DETECTION_SCORES, score_frames(read_scene(run_dir), frames, masks))
    draw_detection_sheet(run_dir, frames, run_dir / names.DETECTION_SHEET)


STAGE = Stage("detect", needs=NEEDS, work=_detect)
run_detect = STAGE.run
