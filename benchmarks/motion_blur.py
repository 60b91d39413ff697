"""What motion blur costs: the second Cycles render of a frame whose colour sensor is on.

Paper scene (seed 7) at the config's default quality (1 sample, fast denoise), 320x240 and
640x480; scan-like poses, each exposed while the camera moves 1.5 m/s sideways (the planner's
speed limit) and turns 0.3 rad/s for 25 ms (the longest default exposure). Per frame, the
medians with min and max of: the ideal render (`CyclesRenderer.render`), the blurred one
(`render_blurred`), and a whole frame of `FrameWorker.render_pose` (PNG encoding included) with
the sensor off, on for a still camera (the sensor model without blur) and on for the moving one: wall seconds, and the process's CPU seconds (all
its threads), which other jobs on a shared machine disturb far less.

    .venv/bin/python benchmarks/motion_blur.py [--repeats 4] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from common import scan_poses, summary

from renderloop.config import load_config
from renderloop.render.executor import FrameWorker
from renderloop.robot.kinematics import homogeneous, rot_y
from renderloop.scene.generate import generate_scene

SPEED, TURN, EXPOSURE = 1.5, 0.3, 0.025  # m/s, rad/s, s


def shutter(pose: np.ndarray) -> np.ndarray:
    """The shutter's two poses about `pose`: sideways along optical x, turning about optical y."""
    poses = []
    for side in (-0.5, 0.5):
        moved = pose @ homogeneous(rot_y(side * TURN * EXPOSURE), (side * SPEED * EXPOSURE, 0.0, 0.0))
        poses.append(moved)
    return np.array(poses)


def timed(call) -> tuple[float, float]:
    """Wall and CPU seconds of `call()`."""
    wall, cpu = time.perf_counter(), time.process_time()
    call()
    return time.perf_counter() - wall, time.process_time() - cpu


def measure(config, scene, poses: list[np.ndarray]) -> dict[str, dict[str, float]]:
    sensor_on = config.override({"camera": {"sensor": {"enabled": True}}})
    worker = FrameWorker(sensor_on, scene)  # the demo preset's backend: Cycles
    try:
        renderer = worker.renderer
        renderer.render(poses[0])  # the first frame also syncs the scene
        renderer.render_blurred(*shutter(poses[0]))  # and the first blurred one the motion settings
        ideal = [timed(lambda: renderer.render(pose)) for pose in poses]
        blurred = [timed(lambda: renderer.render_blurred(*shutter(pose))) for pose in poses]
        frame_on = [timed(lambda: worker.render_pose(0, pose, shutter(pose))) for pose in poses]
        frame_still = [timed(lambda: worker.render_pose(0, pose)) for pose in poses]
        worker.config = config  # the same renderer, the sensor off
        frame_off = [timed(lambda: worker.render_pose(0, pose)) for pose in poses]
    finally:
        worker.close()
    figures = {"ideal_render": ideal, "blurred_render": blurred, "frame_sensor_off": frame_off,
               "frame_sensor_still": frame_still, "frame_sensor_blurred": frame_on}
    results = {}
    for name, times in figures.items():
        results[f"{name}_s"] = summary([wall for wall, _ in times])
        results[f"{name}_cpu_s"] = summary([cpu for _, cpu in times])
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=4)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    paper = load_config("paper", seed=7)
    scene = generate_scene(paper)
    poses = scan_poses(scene, args.repeats)
    results = {}
    for width, height in ((320, 240), (640, 480)):
        config = paper.override({"camera": {"width": width, "height": height}})
        results[f"{width}x{height}"] = measure(config, scene, poses)
    print(f"motion blur: paper scene, {paper.renderer.samples} spp, denoise {paper.renderer.denoise}, "
          f"{len(poses)} poses, camera {SPEED} m/s and {TURN} rad/s over {EXPOSURE * 1000:.0f} ms")
    print(f"{'size':<10}{'figure':<26}{'median':>10}{'min':>10}{'max':>10}")
    for size, figures in results.items():
        for name, value in figures.items():
            print(f"{size:<10}{name:<26}{value['median']:>10.3f}{value['min']:>10.3f}{value['max']:>10.3f}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
