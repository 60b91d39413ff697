"""What a run directory holds, read once for the exporters, tolerating stages not yet run.

An export takes what exists and names what is missing: a run flown but not rendered
still makes a bag of its flight, so `missing` lists the absent pieces (the CLI says
them in one line) instead of refusing. What exists but is malformed is still a
UserError from the readers the stages use.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from renderloop.config import Config
from renderloop.counting.stage import read_counts, read_detections
from renderloop.io import rundir
from renderloop.io.csvtable import read_csv
from renderloop.planning.stage import read_waypoints
from renderloop.planning.trajectory import HEADER as TRAJECTORY_HEADER
from renderloop.planning.waypoints import Waypoint
from renderloop.render.camera import Intrinsics, read_camera_info
from renderloop.render.frames import frame_name, sensor_depth_dir
from renderloop.render.stage import load_poses
from renderloop.scene.model import Scene, load_scene
from renderloop.sim.stage import FLIGHT_HEADER


@dataclass(frozen=True)
class Frame:
    """One camera frame: its pose (T_world_optical) and the image files that exist for it."""

    index: int
    timestamp: float
    pose: np.ndarray
    rgb: Path
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
    detections: dict[int, list[dict]] | None = None  # frame index -> detections of detections.json
    counts: dict | None = None
    missing: list[str] = field(default_factory=list)


def _optional(run_dir: Path, name: str, missing: list[str]) -> Path | None:
    path = run_dir / name
    if path.is_file():
        return path
    missing.append(name)
    return None


def _frames(run_dir: Path, missing: list[str]) -> list[Frame]:
    if _optional(run_dir, "groundtruth.txt", missing) is None:
        return []
    times, poses = load_poses(run_dir)
    depth_dir = sensor_depth_dir(run_dir)
    frames = []
    for index, (timestamp, pose) in enumerate(zip(times, poses)):
        paths = [run_dir / folder / frame_name(index) for folder in ("rgb", depth_dir, "masks")]
        if all(path.is_file() for path in paths):
            frames.append(Frame(index, float(timestamp), pose, *paths))
    if len(frames) < len(poses):
        missing.append(f"frames ({len(frames)} of {len(poses)} rendered)")
    return frames


def read_run(run_dir: Path) -> RunContents:
    run_dir = Path(run_dir)
    contents = RunContents(run_dir, rundir.read_config(run_dir))
    missing = contents.missing
    if path := _optional(run_dir, "scene.json", missing):
        contents.scene = load_scene(path)
    if path := _optional(run_dir, "waypoints.csv", missing):
        contents.waypoints = read_waypoints(path)
    if path := _optional(run_dir, "trajectory.csv", missing):
        contents.trajectory = read_csv(path, TRAJECTORY_HEADER)
    if path := _optional(run_dir, "flight.csv", missing):
        table = read_csv(path, FLIGHT_HEADER)
        contents.flight = {name: table[:, column] for column, name in enumerate(FLIGHT_HEADER)}
    contents.frames = _frames(run_dir, missing)
    if contents.frames or (run_dir / "camera_info.yaml").is_file():
        contents.intrinsics = read_camera_info(run_dir / "camera_info.yaml")
    if _optional(run_dir, "detections.json", missing):
        parsed = read_detections(run_dir, len(load_poses(run_dir)[0]))
        contents.detections = {frame.index: [d.model_dump() for d in frame.detections] for frame in parsed.frames}
    if _optional(run_dir, "counts.json", missing):
        contents.counts = read_counts(run_dir)
    return contents
