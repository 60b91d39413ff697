"""`renderloop detect DIR`: 2D pepper detections on every frame and their 3D points in the world.

detections.json (UTF-8, SI units):
    {"model": path, "score_threshold": t, "windows": ["2x2", ...], "mirror": m, "depth": "depth_sensor" | "depth",
     "frames": [{"index": i, "timestamp": s, "image": "rgb/NNNNNN.png",
                 "detections": [{"bbox": [x0, y0, x1, y1], "score": p, "label": "ripe" | "unripe",
                                 "position": [x, y, z] | null}]}]}
bbox is in pixels (x1, y1 exclusive edges), position the fruit point in the world
frame, null when the box holds too few depth returns. Depth is the sensor stream
(noisy, with dropouts) when the run rendered one, as a real camera would give.

Frames are processed in order and each frame's result is appended to a cache, so a
bad frame stops the stage with the frames before it kept, and the next run goes on
from there. detection_scores.json scores the detections against the masks (the
simulator's truth) and detections.png shows frames with both.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from renderloop.config import Config, DetectorConfig
from renderloop.errors import UserError
from renderloop.io import rundir
from renderloop.io.atomic import write_json
from renderloop.perception.detector import Detector
from renderloop.perception.fruit_points import fruit_point, ripe_coloured
from renderloop.perception.pointcloud import organised_cloud, to_world
from renderloop.perception.scoring import RunScore
from renderloop.perception.sheet import draw_detection_sheet
from renderloop.render.camera import read_camera_info
from renderloop.render.frames import (
    decode_depth,
    frame_name,
    read_png,
    sensor_depth_dir,
)
from renderloop.render.stage import load_poses
from renderloop.scene.model import load_scene

INPUTS = ("config.yaml", "scene.json", "groundtruth.txt", "rgb.txt", "depth.txt", "camera_info.yaml")
OUTPUTS = ("detections.json", "detection_scores.json", "detections.png")
CACHE = ".detections.cache.jsonl"

Progress = Callable[[int, int], None]


def _read_cache(path: Path, model: str) -> list[dict]:
    """Frames already done by this model; a torn last line (a kill mid-write) is dropped."""
    frames = []
    if not path.is_file():
        return frames
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:
            break
        if entry.get("model") != model or entry["frame"]["index"] != len(frames):
            return []
        frames.append(entry["frame"])
    return frames


def read_rgb_frame(run_dir: Path, index: int) -> np.ndarray:
    path = run_dir / "rgb" / frame_name(index)
    rgb = read_png(path, np.uint8)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise UserError(f"{path}: not an RGB image")
    return rgb


def detect_frame(detector: Detector, run_dir: Path, index: int, timestamp: float, pose: np.ndarray,
                 depth_dir: str, settings: DetectorConfig, intrinsics) -> dict:
    rgb = read_rgb_frame(run_dir, index)
    depth_path = run_dir / depth_dir / frame_name(index)
    depth = decode_depth(read_png(depth_path, np.uint16))
    if depth.shape != rgb.shape[:2]:
        raise UserError(f"{depth_path}: depth is {depth.shape[1]}x{depth.shape[0]} but the RGB frame is {rgb.shape[1]}x{rgb.shape[0]}")
    if depth.shape != (intrinsics.height, intrinsics.width):
        raise UserError(f"{depth_path}: {depth.shape[1]}x{depth.shape[0]} does not match camera_info.yaml")
    cloud, ripe_pixels = organised_cloud(depth, intrinsics), ripe_coloured(rgb)
    detections = []
    for detection in detector.detect(rgb, settings.score_threshold, settings.layouts, settings.mirror):
        point = fruit_point(cloud, detection.bbox, intrinsics.fx, ripe_pixels if detection.label == "ripe" else None)
        world = None if point is None else [round(float(v), 5) for v in to_world(point, pose)]
        detections.append({**detection.to_json(), "position": world})
    return {"index": index, "timestamp": round(float(timestamp), 6), "image": f"rgb/{frame_name(index)}", "detections": detections}


def run_detect(run_dir: Path, config: Config, force: bool = False, model: Path | None = None,
               progress: Progress | None = None) -> bool:
    run_dir = Path(run_dir)
    rundir.require(run_dir, INPUTS, "render")
    if not force and model is None and rundir.complete(run_dir, OUTPUTS, INPUTS):
        return False
    detector = Detector(model if model is not None else config.detector.model)
    settings = config.detector
    times, poses = load_poses(run_dir)
    intrinsics = read_camera_info(run_dir / "camera_info.yaml")
    depth_dir = sensor_depth_dir(run_dir)
    cache = run_dir / CACHE
    key = f"{detector.path}@{settings.score_threshold}@{','.join(settings.windows)}@{settings.mirror}@{depth_dir}"
    frames = [] if force else _read_cache(cache, key)
    with open(cache, "w", encoding="utf-8") as out:  # rewritten from what was valid, then appended to
        out.writelines(json.dumps({"model": key, "frame": frame}) + "\n" for frame in frames)
        out.flush()
        for index in range(len(frames), len(poses)):
            if progress:
                progress(index, len(poses))
            frame = detect_frame(detector, run_dir, index, times[index], poses[index], depth_dir, settings, intrinsics)
            out.write(json.dumps({"model": key, "frame": frame}) + "\n")
            out.flush()
            frames.append(frame)
    if progress:
        progress(len(poses), len(poses))
    write_json(run_dir / "detections.json", {"model": str(detector.path), "score_threshold": settings.score_threshold,
                                             "windows": list(settings.windows), "mirror": settings.mirror, "depth": depth_dir,
                                             "frames": frames})
    write_json(run_dir / "detection_scores.json", score_run(run_dir, frames))
    draw_detection_sheet(run_dir, frames, run_dir / "detections.png")
    cache.unlink(missing_ok=True)
    return True


def score_run(run_dir: Path, frames: list[dict]) -> dict:
    scene = load_scene(run_dir / "scene.json")
    score = RunScore.of_scene(scene)
    for frame in frames:
        score.add(frame["detections"], read_png(run_dir / "masks" / frame_name(frame["index"]), np.uint16))
    return score.summary()
