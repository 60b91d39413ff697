"""Speed of `renderloop render`: Cycles seconds per frame and where they go, raster ms per frame, workers.

Figures measured side by side in one run on this machine:
- Cycles, paper scene, 640x480 at the config's default quality and at 128 samples: seconds per
  frame, and the share inside path tracing (Cycles' render_time over the wall time of a frame);
- raster backend, milliseconds per 640x480 frame, with the default look and without shadows or antialiasing;
- frames per second of the whole render stage (PNG encoding and writing included) on the
  demo run with 1 and 2 local workers and on a local 2-CPU Ray cluster, Cycles at the demo's
  default quality.
Medians over repeats, with min and max.

    .venv/bin/python benchmarks/render.py [--repeats 3] [--high-samples 128] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from common import scan_poses, summary

from renderloop.config import load_config
from renderloop.parallel import Executor
from renderloop.planning.stage import run_plan
from renderloop.render.camera import Intrinsics
from renderloop.render.cycles import CyclesRenderer
from renderloop.render.raster import RasterRenderer
from renderloop.render.stage import run_render
from renderloop.scene.generate import generate_scene
from renderloop.scene.stage import run_scene
from renderloop.sim.stage import run_fly


def cycles_frames(scene, config, poses) -> tuple[list[float], list[float]]:
    seconds, shares = [], []
    with CyclesRenderer(scene, config, Intrinsics.from_config(config.camera)) as renderer:
        renderer.render(poses[0])  # the first frame also syncs the scene
        for pose in poses:
            timings = renderer.render(pose).timings
            seconds.append(timings["total"])
            shares.append(timings["render_time"] / timings["total"])
    return seconds, shares


def stage_fps(workers: int, run_dir: Path, config, kind: str = "local") -> float:
    start = time.perf_counter()
    run_render(run_dir, config, force=True, executor=Executor(kind=kind, workers=workers))
    return len(list((run_dir / "rgb").iterdir())) / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--high-samples", type=int, default=128)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()

    paper = load_config("paper", seed=7)
    scene = generate_scene(paper)
    poses = scan_poses(scene, args.repeats)
    default_seconds, default_share = cycles_frames(scene, paper, poses)
    high = paper.override({"renderer": {"samples": args.high_samples}})
    high_seconds, high_share = cycles_frames(scene, high, poses[:1])
    raster_ms = {}
    for name, look in (("default", {}), ("plain", {"shadows": False, "antialias": 0})):
        config = paper.override({"renderer": {"raster": look}})
        with RasterRenderer(scene, config, Intrinsics.from_config(paper.camera)) as raster:
            raster.render(poses[0])
            raster_ms[name] = [1000 * raster.render(pose).timings["total"] for pose in poses * 5]

    demo = load_config("demo")
    demo = demo.override({"camera": {"rate_hz": 0.25}})  # about 20 frames
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp)
        run_scene(run_dir, demo)
        run_plan(run_dir, demo)
        run_fly(run_dir, demo)
        fps = {workers: stage_fps(workers, run_dir, demo) for workers in (1, 2)}
        fps["ray"] = stage_fps(2, run_dir, demo, kind="ray")  # a local 2-CPU Ray cluster, started inside the timing

    results = {
        "cycles_default_s_per_frame": summary(default_seconds),
        "cycles_default_path_tracing_share": summary(default_share),
        f"cycles_{args.high_samples}spp_s_per_frame": summary(high_seconds),
        f"cycles_{args.high_samples}spp_path_tracing_share": summary(high_share),
        "raster_ms_per_frame": summary(raster_ms["default"]),
        "raster_ms_per_frame_no_shadows_or_antialiasing": summary(raster_ms["plain"]),
        "render_stage_fps_1_worker": fps[1],
        "render_stage_fps_2_workers": fps[2],
        "speedup_2_workers": fps[2] / fps[1],
        "render_stage_fps_ray_2_cpus": fps["ray"],
        "speedup_ray_2_cpus": fps["ray"] / fps[1],
        "default_quality": paper.renderer.model_dump(mode="json"),
    }
    print(f"render benchmark: paper scene 640x480 ({paper.renderer.samples} spp, denoise {paper.renderer.denoise_quality}); "
          f"render stage on {demo.camera.width}x{demo.camera.height} demo frames")
    print(f"{'figure':<38}{'median':>10}{'min':>10}{'max':>10}")
    for name, value in results.items():
        if isinstance(value, dict) and "median" in value:
            print(f"{name:<38}{value['median']:>10.3f}{value['min']:>10.3f}{value['max']:>10.3f}")
        elif isinstance(value, float):
            print(f"{name:<38}{value:>10.3f}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
