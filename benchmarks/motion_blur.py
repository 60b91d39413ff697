"""What motion blur costs: the second Cycles render of a frame whose colour sensor is on.

Paper scene (seed 7) at the config's default quality (1 sample, fast denoise), 320x240 and
640x480; scan-like poses, each exposed while the camera moves 1.5 m/s sideways (the planner's
speed limit) and turns 0.3 rad/s for 25 ms (the longest default exposure). Per frame, the
medians with min and max of: the ideal render (`CyclesRenderer.render`), the blurred one
(`render_blurred`), and a whole frame of `FrameWorker.render_pose` (PNG encoding included) with
the sensor off, on for a still camera (the sensor model without blur) and on for the moving one: wall seconds, and the process's CPU seconds (all
its threads), which other jobs on a shared machine disturb far less; and the scene's re-sync
(Cycles' `synchronization_time`, its least and most over the frames of both sizes) before a
blurred frame's still render, which follows the previous frame's blurred one. The docs show the
CPU seconds of the whole frames.

    .venv/bin/python benchmarks/motion_blur.py [--repeats 4] [--name render_motion_blur]
"""

from __future__ import annotations

import argparse

import numpy as np
from common import save_result, scan_poses, summary, timed

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


def measure(config, scene, poses: list[np.ndarray]) -> dict[str, dict[str, float]]:
    """Summaries of wall and CPU seconds a frame (`NAME_s`, `NAME_cpu_s`), and of the re-sync (`resync_s`)."""
    sensor_on = config.override({"camera": {"sensor": {"enabled": True}}})
    worker = FrameWorker(sensor_on, scene)  # the demo preset's backend: Cycles
    try:
        renderer = worker.renderer
        renderer.render(poses[0])  # the first frame also syncs the scene
        renderer.render_blurred(*shutter(poses[0]))  # and the first blurred one the motion settings
        ideal = [timed(renderer.render, pose) for pose in poses]
        blurred = [timed(renderer.render_blurred, *shutter(pose)) for pose in poses]
        frame_on = [timed(worker.render_pose, 0, pose, shutter(pose)) for pose in poses]
        frame_still = [timed(worker.render_pose, 0, pose) for pose in poses]
        worker.config = config  # the same renderer, the sensor off
        frame_off = [timed(worker.render_pose, 0, pose) for pose in poses]
    finally:
        worker.close()
    figures = {"ideal_render": ideal, "blurred_render": blurred, "frame_sensor_off": frame_off,
               "frame_sensor_still": frame_still, "frame_sensor_blurred": frame_on}
    results = {}
    for name, times in figures.items():
        results[f"{name}_s"] = summary([wall for _, wall, _ in times])
        results[f"{name}_cpu_s"] = summary([cpu for *_, cpu in times])
    # render_pose's timings are its still render's: in a blurred frame it follows the previous frame's blurred render
    results["resync_s"] = summary([timings["synchronization_time"] for (_, _, timings), _, _ in frame_on])
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=4)
    parser.add_argument("--name", default="render_motion_blur", help="Results file: benchmarks/results/NAME.json.")
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
    columns = {"frame_sensor_off_cpu_s": "sensor off", "frame_sensor_still_cpu_s": "sensor on, at rest",
               "frame_sensor_blurred_cpu_s": "sensor on, motion blur"}
    blur_factors = [figures["frame_sensor_blurred_cpu_s"]["median"] / figures["frame_sensor_off_cpu_s"]["median"]
                    for figures in results.values()]
    print(save_result(args.name, {
        "table": {"columns": ["frame size", *columns.values()],
                  "rows": [[size, *(round(figures[key]["median"], 2) for key in columns)] for size, figures in results.items()]},
        "blur_factor_min": round(min(blur_factors), 1), "blur_factor_max": round(max(blur_factors), 1),
        "resync_min_s": round(min(figures["resync_s"]["min"] for figures in results.values()), 1),
        "resync_max_s": round(max(figures["resync_s"]["max"] for figures in results.values()), 1),
    }))


if __name__ == "__main__":
    main()
