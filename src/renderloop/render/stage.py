"""`renderloop render DIR`: RGB, depth and instance masks at every camera pose of groundtruth.txt.

`render.json` records what the frames in the directory were rendered from (poses,
scene, camera, renderer settings, backend). A render that finds the same record
resumes, skipping finished frames; one that finds another record starts over,
so frames of two different inputs never mix.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

from renderloop.config import BouncesConfig, Config
from renderloop.errors import UserError
from renderloop.io import rundir
from renderloop.io.atomic import write_json, write_text
from renderloop.io.tum import read_tum
from renderloop.render.camera import Intrinsics, write_camera_info
from renderloop.render.contact_sheet import draw_contact_sheet
from renderloop.render.executor import BACKENDS, render_local, render_ray
from renderloop.render.frames import frame_done, frame_name, write_frame
from renderloop.robot.kinematics import homogeneous
from renderloop.scene.model import load_scene

INPUTS = ("config.yaml", "scene.json", "groundtruth.txt")
OUTPUTS = ("rgb.txt", "depth.txt", "camera_info.yaml", "contact_sheet.png")
MANIFEST = "render.json"
FRAME_DIRS = ("rgb", "depth", "depth_sensor", "masks")

Progress = Callable[[int, int], None]


def load_poses(run_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    times, positions, rotations = read_tum(run_dir / "groundtruth.txt")
    return times, np.array([homogeneous(r, p) for r, p in zip(rotations, positions)])


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _manifest(run_dir: Path, config: Config, backend: str, poses: np.ndarray) -> dict:
    return {
        "backend": backend,
        "frames": len(poses),
        "poses_sha256": _sha256(np.ascontiguousarray(poses).tobytes()),
        "scene_sha256": _sha256((run_dir / "scene.json").read_bytes()),
        "seed": config.seed,
        "camera": config.camera.model_dump(mode="json"),
        # the thread count says how fast frames come, not what they hold (kept at 0 so older records still match)
        "renderer": {**config.renderer.model_dump(mode="json", exclude={"backend"}), "threads": 0},
    }


def _recorded(run_dir: Path) -> dict | None:
    path = run_dir / MANIFEST
    try:
        recorded = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else None
    except (json.JSONDecodeError, UnicodeDecodeError):
        return None  # a damaged record means unknown frames: start over
    if isinstance(recorded, dict) and isinstance(recorded.get("renderer"), dict):
        # a record from before the bounces were configurable: its frames had today's defaults, then hard-coded
        recorded["renderer"] = {"bounces": BouncesConfig().model_dump(mode="json"), **recorded["renderer"]}
    return recorded


def _start_over(run_dir: Path, manifest: dict) -> None:
    for name in (*FRAME_DIRS, *OUTPUTS):
        target = run_dir / name
        shutil.rmtree(target) if target.is_dir() else target.unlink(missing_ok=True)
    write_json(run_dir / MANIFEST, manifest)


def _index_file(run_dir: Path, name: str, times: np.ndarray) -> None:
    lines = [f"# {name} images of renderloop, TUM RGB-D layout", "# timestamp filename"]
    lines += [f"{t:.6f} {name}/{frame_name(i)}" for i, t in enumerate(times)]
    write_text(run_dir / f"{name}.txt", "\n".join(lines) + "\n")


def run_render(
    run_dir: Path, config: Config, force: bool = False, backend: str | None = None, workers: int = 1,
    executor: str = "local", address: str | None = None, progress: Progress | None = None,
) -> bool:
    run_dir = Path(run_dir)
    backend = backend or config.renderer.backend
    if backend not in BACKENDS:
        raise UserError(f"unknown backend {backend!r} (choose from: {', '.join(BACKENDS)})")
    if executor not in ("local", "ray"):
        raise UserError(f"unknown executor {executor!r} (choose from: local, ray)")
    rundir.require(run_dir, INPUTS, "fly")
    times, poses = load_poses(run_dir)
    manifest = _manifest(run_dir, config, backend, poses)
    same = _recorded(run_dir) == manifest
    if not force and same and rundir.complete(run_dir, OUTPUTS, INPUTS):
        if progress:
            progress(len(poses), len(poses))
        return False
    if force or not same:
        _start_over(run_dir, manifest)

    sensor = config.renderer.depth_noise.enabled
    todo = [i for i in range(len(poses)) if not frame_done(run_dir, i, sensor)]
    done = len(poses) - len(todo)
    if progress:
        progress(done, len(poses))
    if todo:
        scene = load_scene(run_dir / "scene.json")
        if executor == "ray":
            batches = render_ray(config, scene, poses, backend, todo, workers, address)
        else:
            batches = render_local(config, scene, poses, backend, todo, workers)
        for batch in batches:
            for index, files, _ in batch:
                write_frame(run_dir, index, files)
            done += len(batch)
            if progress:
                progress(done, len(poses))

    write_camera_info(run_dir / "camera_info.yaml", Intrinsics.from_config(config.camera))
    _index_file(run_dir, "rgb", times)
    _index_file(run_dir, "depth", times)
    if sensor:
        _index_file(run_dir, "depth_sensor", times)
    draw_contact_sheet(run_dir, len(poses), run_dir / "contact_sheet.png")
    return True

