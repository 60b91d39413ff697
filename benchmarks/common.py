"""What the benchmark scripts share: how repeats are summarised, and the scan-like camera pose."""

from __future__ import annotations

import statistics
import time

import numpy as np

from renderloop.render.camera import Intrinsics
from renderloop.robot.kinematics import look_at


def summary(values: list[float]) -> dict[str, float]:
    """Median with min and max, so the noise of the machine stays visible."""
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def scan_poses(scene, count: int) -> list[np.ndarray]:
    """Camera poses like the scan's: 0.44 m from a bearing plant, aimed at its centroid."""
    poses = []
    for plant in [p for p in scene.plants if p.bearing][:count]:
        target = np.array([plant.position[0], plant.position[1], (plant.position[2] + plant.pot.height + plant.bounds.max[2]) / 2])
        poses.append(look_at(target + np.array([-0.44, 0.05, 0.1]), target))
    return poses


def timed(function, *args):
    """The result of `function(*args)`, its wall seconds and this process's CPU seconds."""
    wall, cpu = time.perf_counter(), time.process_time()
    result = function(*args)
    return result, time.perf_counter() - wall, time.process_time() - cpu


def render_costs(scene, config, poses: list[np.ndarray]) -> dict:
    """Cycles build, first frame and per-frame cost (wall and CPU s), and raster build and frame cost, on `poses`."""
    from renderloop.render.cycles import CyclesRenderer
    from renderloop.render.raster import RasterRenderer

    intrinsics, out = Intrinsics.from_config(config.camera), {}
    renderer, out["cycles_build_s"], out["cycles_build_cpu_s"] = timed(CyclesRenderer, scene, config, intrinsics)
    with renderer:
        _, out["cycles_first_frame_s"], out["cycles_first_frame_cpu_s"] = timed(renderer.render, poses[0])
        frames = [timed(renderer.render, pose) for pose in poses]
    out["cycles_frame_s"] = summary([wall for _, wall, _ in frames])
    out["cycles_frame_cpu_s"] = summary([cpu for *_, cpu in frames])
    raster, out["raster_build_s"], _ = timed(RasterRenderer, scene, config, intrinsics)
    with raster:
        raster.render(poses[0])
        out["raster_frame_ms"] = summary([1000 * timed(raster.render, pose)[1] for pose in poses])
    return out
