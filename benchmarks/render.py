"""Speed of `renderloop render`: Cycles seconds per frame and where they go, raster ms per frame, workers.

Figures measured side by side in one run on this machine:
- Cycles, paper scene, 640x480 at the config's default quality and at 128 samples: seconds per
  frame, and the share inside path tracing (Cycles' render_time over the wall time of a frame),
  at the default quality also the share of path tracing alone (the render_time of the same
  frames without denoising);
- raster backend, milliseconds per 640x480 frame, with the default look and without shadows or antialiasing;
- frames per second of the whole render stage (PNG encoding and writing included) on the
  demo run with 1 and 2 local workers and on a local 2-CPU Ray cluster, Cycles at the demo's
  default quality.
Medians over repeats, with min and max.

    .venv/bin/python benchmarks/render.py [--repeats 3] [--high-samples 128] [--name render_speed] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from common import save_result, scan_poses, summary

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


def cycles_frames(scene, config, poses) -> list[dict[str, float]]:
    """Each pose's frame timings: `total` (wall seconds) and Cycles' own `render_time`."""
    with CyclesRenderer(scene, config, Intrinsics.from_config(config.camera)) as renderer:
        renderer.render(poses[0])  # the first frame also syncs the scene
        return [renderer.render(pose).timings for pose in poses]


def share(timings: list[dict[str, float]], of: list[dict[str, float]] | None = None) -> list[float]:
    """Each frame's `render_time` over the `total` of the same pose's frame in `of` (default: the frame itself)."""
    return [frame["render_time"] / whole["total"] for frame, whole in zip(timings, of or timings, strict=True)]


def stage_fps(workers: int, run_dir: Path, config, kind: str = "local") -> float:
    start = time.perf_counter()
    run_render(run_dir, config, force=True, executor=Executor(kind=kind, workers=workers))
    return len(list((run_dir / "rgb").iterdir())) / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--high-samples", type=int, default=128)
    parser.add_argument("--name", default="render_speed", help="Results file: benchmarks/results/NAME.json.")
    # benchmarks/run.py reads every measurement from here; its short runs must not replace the docs' figures
    parser.add_argument("--json", type=Path, help="write every measurement here instead of the results file")
    args = parser.parse_args()

    paper = load_config("paper", seed=7)
    scene = generate_scene(paper)
    poses = scan_poses(scene, args.repeats)
    default = cycles_frames(scene, paper, poses)
    not_denoised = cycles_frames(scene, paper.override({"renderer": {"denoise": False}}), poses)
    high = paper.override({"renderer": {"samples": args.high_samples}})
    high_frames = cycles_frames(scene, high, poses[:1])
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
        demo_frames = len(list((run_dir / "rgb").iterdir()))

    results = {
        "cycles_default_s_per_frame": summary([frame["total"] for frame in default]),
        "cycles_default_path_tracing_share": summary(share(default)),
        "cycles_default_path_tracing_alone_share": summary(share(not_denoised, of=default)),
        f"cycles_{args.high_samples}spp_s_per_frame": summary([frame["total"] for frame in high_frames]),
        f"cycles_{args.high_samples}spp_path_tracing_share": summary(share(high_frames)),
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
        return
    seconds, inside = results["cycles_default_s_per_frame"], results["cycles_default_path_tracing_share"]
    alone = results["cycles_default_path_tracing_alone_share"]["median"]
    high_seconds = results[f"cycles_{args.high_samples}spp_s_per_frame"]["median"]
    high_inside = results[f"cycles_{args.high_samples}spp_path_tracing_share"]["median"]
    quality, camera = paper.renderer, paper.camera
    rows = [
        [f"Cycles, paper scene {camera.width}x{camera.height}, default quality ({quality.samples} spp, "
         f"{quality.denoise_quality} denoise): s per frame",
         f"{seconds['median']:.3f} ({seconds['min']:.3f}-{seconds['max']:.3f})"],
        ["share of that inside Cycles' render: path tracing and denoising / path tracing alone",
         f"{100 * inside['median']:.1f} % ({100 * inside['min']:.1f}-{100 * inside['max']:.1f}) / about {100 * alone:.0f} %"],
        [f"Cycles at {args.high_samples} spp ({'adaptive' if high.renderer.adaptive_threshold else 'not adaptive'}): "
         "s per frame / share inside the render", f"{high_seconds:.1f} / {100 * high_inside:.1f} %"],
        [f"render stage, {demo_frames} demo frames {demo.camera.width}x{demo.camera.height}: frames/s with 1 / 2 workers "
         "/ local 2-CPU Ray", f"{fps[1]:.2f} / {fps[2]:.2f} / {fps['ray']:.2f}"],
    ]
    figures = {"cycles_frame_s": round(seconds["median"], 3),
               "table": {"columns": ["figure", "median (min-max)"], "rows": rows}}
    print(save_result(args.name, figures))


if __name__ == "__main__":
    main()
