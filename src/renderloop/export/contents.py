"""What a run directory holds, read once for the exporters, tolerating stages not yet run.

An export takes what exists and names what is missing: a run flown but not rendered
still makes a bag of its flight, so `missing` lists the absent pieces (the CLI says
them in one line) instead of refusing. What exists but is malformed is still a
UserError from the readers the stages use, and every frame's images are checked from
their headers to be of the camera's size (`camera_info.yaml`) before an exporter decodes
one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.io.images import check_image
from renderloop.planning.waypoints import Waypoint, read_waypoints
from renderloop.render.camera import Intrinsics, read_camera_info
from renderloop.render.frames import sensor_depth_dir, sensor_rgb_dir
from renderloop.rundir import files, names
from renderloop.rundir.models import Counts, Detection
from renderloop.scene.model import Scene, read_scene


@dataclass(frozen=True)
class Frame:
    """One camera frame: its pose (T_world_optical) and the image files that exist for it."""

    index: int
    timestamp: float
    pose: np.ndarray
    rgb: Path  # the sensor stream when the run rendered one (what a real camera gives), else the ideal colour
    depth: Path  # the sensor stream when the run rendered one (what a real camera gives), else the ideal depth
    mask: Path


@dataclass
class RunContents:
    run_dir: Path
    config: Config
    scene: Scene | None = None
    waypoints: list[Waypoint] | None = None
    trajectory: np.ndarray | None = None  # rows of trajectory.csv: t, q*, q̇*, q̈* (7 DoF each)
    flight: dict[str, np.ndarray] | None = None  # flight.csv columns by name
    intrinsics: Intrinsics | None = None
    frames: list[Frame] = field(default_factory=list)
    detections: dict[int, list[Detection]] | None = None  # frame index -> its detections
    counts: Counts | None = None
    missing: list[str] = field(default_factory=list)


def _present(run_dir: Path, name: str, missing: list[str]) -> bool:
    if (run_dir / name).is_file():
        return True
    missing.append(name)
    return False


def _frames(run_dir: Path, missing: list[str]) -> list[Frame]:
    if not _present(run_dir, names.POSES, missing):
        return []
    times, poses = files.read_poses(run_dir)
    streams = (sensor_rgb_dir(run_dir), sensor_depth_dir(run_dir), names.MASKS)
    frames = []
    for index, (timestamp, pose) in enumerate(zip(times, poses)):
        paths = [run_dir / names.frame_file(stream, index) for stream in streams]
        if all(path.is_file() for path in paths):
            frames.append(Frame(index, float(timestamp), pose, *paths))
    if len(frames) < len(poses):
        missing.append(f"frames ({len(frames)} of {len(poses)} rendered)")
    return frames


def _check_sizes(run_dir: Path, frames: list[Frame], intrinsics: Intrinsics) -> None:
    """Every image of every frame the camera's size, from its header alone (nothing is decoded): an exporter
    decodes them one by one later, and one of another size would fail deep inside it."""
    for frame in frames:
        for path in (frame.rgb, frame.depth, frame.mask):
            width, height = check_image(path, formats=("PNG",))
            if (width, height) != (intrinsics.width, intrinsics.height):
                raise UserError(f"{path}: {width}x{height} px, but {run_dir / names.CAMERA_INFO} says "
                                f"{intrinsics.width}x{intrinsics.height}")


def read_run(run_dir: Path) -> RunContents:
    run_dir = Path(run_dir)
    contents = RunContents(run_dir, files.read_config(run_dir))
    missing = contents.missing
    if _present(run_dir, names.SCENE, missing):
        contents.scene = read_scene(run_dir)
    if _present(run_dir, names.WAYPOINTS, missing):
        contents.waypoints = read_waypoints(run_dir)
    if _present(run_dir, names.TRAJECTORY, missing):
        contents.trajectory = files.read_trajectory(run_dir)
    if _present(run_dir, names.FLIGHT, missing):
        contents.flight = files.read_flight(run_dir)
    contents.frames = _frames(run_dir, missing)
    if contents.frames or (run_dir / names.CAMERA_INFO).is_file():
        contents.intrinsics = read_camera_info(run_dir)
        _check_sizes(run_dir, contents.frames, contents.intrinsics)
    if _present(run_dir, names.DETECTIONS, missing):
        parsed = files.read_detections(run_dir, len(files.read_poses(run_dir)[0]))
        contents.detections = {frame.index: frame.detections for frame in parsed.frames}
    if _present(run_dir, names.COUNTS, missing):
        contents.counts = files.read_counts(run_dir)
    return contents
