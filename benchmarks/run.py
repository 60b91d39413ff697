"""Every stage measured on this machine, in one table: each figure beside its reference from the same run.

Runs benchmarks/fly.py, render.py and detect.py (each measures side by side in its own
process, so one's threads and caches do not colour another's figures), times the counting
of paper rows here, and runs the whole demo and paper pipelines as child processes for wall
time and peak memory (the maximum resident set of the largest process, as /usr/bin/time -v
reports it). Medians over repeats, with min and max. The paper run renders at
--paper-rate-hz (the preset's 5 Hz is some 3 000 Cycles frames, hours on two cores).

    .venv/bin/python benchmarks/run.py [--quick] [--name NAME]

Writes benchmarks/results/run.json (or NAME.json): the table the docs show (docs/benchmarks.md) and the figures the
README names; a --quick run writes nothing unless given --name.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from common import RESULTS_FOLDER, save_result, summary

from renderloop.config import load_config
from renderloop.counting.cluster import count_rows
from renderloop.scene.generate import generate_scene

HERE = Path(__file__).resolve().parent


def sub_benchmark(name: str, *args: str) -> dict:
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / f"{name}.json"
        subprocess.run([sys.executable, str(HERE / f"{name}.py"), *args, "--json", str(out)], check=True)
        return json.loads(out.read_text())


def saved_figures(name: str, results: str, *args: str) -> dict:
    """The figures `NAME.py` saves as its results file `results`, measured in a process of its own into a scratch
    folder: the docs' files stay as they are."""
    with tempfile.TemporaryDirectory() as folder:
        subprocess.run([sys.executable, str(HERE / f"{name}.py"), *args], check=True, env={**os.environ, RESULTS_FOLDER: folder})
        return json.loads((Path(folder) / f"{results}.json").read_text())["figures"]


def counting_ms_per_row(repeats: int) -> dict:
    """The paper scene's rows counted from 8 noisy views of every ripe fruit plus 10 % strays: the count stage's work;
    and OPTICS alone on each row's fixed set, compiled (`renderloop.counting.optics`) beside scikit-learn's estimator,
    whose labels it must equal."""
    from scipy.spatial.distance import cdist
    from sklearn.cluster import OPTICS

    from renderloop.counting.optics import optics_labels

    config = load_config("paper", seed=7)
    scene = generate_scene(config)
    rng = np.random.default_rng(0)
    centres = np.array([p.center for p in scene.peppers if p.ripe])
    views = np.repeat(centres, 8, axis=0) + rng.normal(0.0, 0.01, (8 * len(centres), 3))
    strays = views[rng.choice(len(views), len(views) // 10)] + rng.normal(0.0, 0.3, (len(views) // 10, 3))
    detections = np.vstack([views, strays])
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        rows = count_rows(scene, detections, "ripe", config.counting, config.seed)
        times.append((time.perf_counter() - start) * 1000 / len(scene.rows))
    counting = config.counting
    fixed_sets = [(cdist(row.clusters.points, row.clusters.points), row.clusters.min_samples)
                  for row in rows if row.clusters.min_samples]  # what the count clustered
    compiled, estimator = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        ours = [optics_labels(d, k, counting.eps, counting.cluster_method) for d, k in fixed_sets]
        compiled.append((time.perf_counter() - start) * 1000 / len(fixed_sets))
        start = time.perf_counter()
        theirs = [OPTICS(min_samples=k, max_eps=counting.eps, cluster_method=counting.cluster_method,
                         metric="precomputed").fit(d).labels_ for d, k in fixed_sets]
        estimator.append((time.perf_counter() - start) * 1000 / len(fixed_sets))
        assert all(np.array_equal(a, b) for a, b in zip(ours, theirs)), "the compiled OPTICS labels differ"
    return {"count": summary(times), "optics_compiled": summary(compiled), "optics_scikit_learn": summary(estimator)}


def whole_run(preset: str, overrides: dict, repeats: int) -> tuple[dict, dict]:
    """Wall seconds and peak resident MB of `renderloop run` from nothing, each repeat in a fresh directory."""
    seconds, megabytes = [], []
    wrapper = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True, capture_output=True); "
               "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as folder:
            config = Path(folder) / "config.yaml"
            config.write_text(yaml.safe_dump(overrides))
            command = [sys.executable, "-m", "renderloop", "run", "--preset", preset, "--config", str(config), "--out", f"{folder}/run"]
            start = time.perf_counter()
            peak_kb = subprocess.run([sys.executable, "-c", wrapper, *command], check=True, capture_output=True, text=True).stdout
            seconds.append(time.perf_counter() - start)
            megabytes.append(int(peak_kb) / 1024)
    return summary(seconds), summary(megabytes)


def row(figure: str, measured: dict | float | str, reference: str = "", ratio: float | None = None) -> list:
    """A row of the docs' table: the figure, its median (three significant digits), min-max, its reference in the
    same run and the ratio to it."""
    if isinstance(measured, dict):
        median, spread = float(f"{measured['median']:.3g}"), f"{measured['min']:.3g}-{measured['max']:.3g}"
    else:
        median, spread = float(f"{measured:.3g}") if isinstance(measured, float) else measured, ""
    return [figure, median, spread, reference, "" if ratio is None else f"{ratio:.3g}x"]


def figures_of(results: dict, paper_rate: float, quick: bool, minutes: float, repeats: int) -> dict:
    """The results file's figures: the table the docs show, and the values the README names."""
    fly, render, detect, counting = results["fly"], results["render"], results["detect"], results["counting_ms_per_row"]
    high = next(k for k in render if k.startswith("cycles_") and k.endswith("spp_s_per_frame") and "default" not in k)
    samples = high.split("_")[1]
    demo_s, demo_mb = results["demo_seconds"], results["demo_peak_mb"]
    rows = [
        row("fly: closed-loop real-time factor, x real time", fly["closed_loop_real_time_factor"],
            "1x real time (Gazebo/RotorS)", fly["closed_loop_real_time_factor"]["median"]),
        row(f"fly: the whole `renderloop fly` process on the {fly['process_simulated_seconds']:.0f} s paper scan, x real time",
            fly["process_real_time_factor"], "goal 100x", fly["process_real_time_factor"]["median"] / 100),
        row("fly: physics steps per second, closed loop / physics alone",
            f"{fly['closed_loop_physics_steps_per_s']['median']:,.0f} / {fly['physics_steps_per_s']['median']:,.0f}"),
        row("render: Cycles s per 640x480 frame, default (1 spp, denoised)", render["cycles_default_s_per_frame"],
            f"{samples}: s per frame", render[high]["median"] / render["cycles_default_s_per_frame"]["median"]),
        row(f"render: Cycles s per 640x480 frame, {samples}", render[high]),
        row("render: share of a Cycles frame inside Cycles' render (path tracing, denoising)",
            render["cycles_default_path_tracing_share"], "goal 0.90"),
        row("render: raster ms per 640x480 frame", render["raster_ms_per_frame"], "Cycles default",
            1000 * render["cycles_default_s_per_frame"]["median"] / render["raster_ms_per_frame"]["median"]),
        row("the same without shadows or multisampling (`renderer.raster`), ms",
            render["raster_ms_per_frame_no_shadows_or_antialiasing"], "default raster",
            render["raster_ms_per_frame"]["median"] / render["raster_ms_per_frame_no_shadows_or_antialiasing"]["median"]),
        row("render stage, 320x240 demo frames: frames per second, 2 workers", render["render_stage_fps_2_workers"],
            "1 worker", render["speedup_2_workers"]),
        row("render stage: frames per second, local Ray cluster of 2 CPUs", render["render_stage_fps_ray_2_cpus"],
            "1 worker", render["speedup_ray_2_cpus"]),
        row("point cloud ms per 640x480 frame", detect["cloud_ms"], "Open3D create_from_depth_image",
            detect["open3d_cloud_ms"] / detect["cloud_ms"] if "open3d_cloud_ms" in detect else None),
        row("detector: ONNX Runtime's speed over torch's, 2 threads", detect["onnx_speed_vs_torch_2_threads"]),
        row("the shipped detector, ms a 640x480 frame on one core: whole frame / 2x2 windows / the default passes",
            f"{detect['whole_frame_ms']} / {detect['windows_2x2_ms']} / {detect['default_ms']}", "goal 50 ms (the default)"),
        row("counting ms per paper row", counting["count"]),
        row("OPTICS ms per paper row, compiled graph (labels checked equal)", counting["optics_compiled"],
            "scikit-learn's OPTICS", counting["optics_scikit_learn"]["median"] / counting["optics_compiled"]["median"]),
        row("demo run (`renderloop run`" + (", raster)" if quick else ")") + ", wall s", demo_s, "goal 300 s",
            300 / demo_s["median"]),
        row("demo run, peak MB", demo_mb),
        row(f"paper run, one seed, camera {paper_rate:g} Hz, wall s / peak MB",
            f"{results['paper_seconds']['median']:.0f} / {results['paper_peak_mb']['median']:.0f}"),
    ]
    return {
        "repeats": repeats, "minutes": round(minutes), "quick": quick,
        "table": {"columns": ["figure", "median", "min-max", "reference, same run", "ratio"], "rows": rows},
        "closed_loop_rtf": round(fly["closed_loop_real_time_factor"]["median"]),
        "process_rtf": round(fly["process_real_time_factor"]["median"]),
        "cycles_default_s": round(render["cycles_default_s_per_frame"]["median"], 2),
        "cycles_high_s": round(render[high]["median"], 1), "cycles_high_samples": samples,
        "demo_wall_s": round(demo_s["median"], 1), "demo_peak_mb": round(demo_mb["median"]),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="few repeats, raster demo and paper runs: a minutes-long smoke run")
    parser.add_argument("--paper-rate-hz", type=float, default=0.2, help="camera rate of the paper run (0.2 Hz: 125 frames)")
    parser.add_argument("--name", help="Results file: benchmarks/results/NAME.json; default run, and none with --quick "
                        "(a smoke run's figures are not the docs')")
    args = parser.parse_args()
    began, repeats = time.perf_counter(), 1 if args.quick else 3
    results = {
        "fly": sub_benchmark("fly", "--repeats", str(repeats), "--seconds", "20" if args.quick else "60"),
        "render": sub_benchmark("render", "--repeats", str(repeats)),
        "detect": saved_figures("detect", "perception_speed", "--repeats", "10" if args.quick else "30"),
        "counting_ms_per_row": counting_ms_per_row(3 if args.quick else 10),
    }
    raster = {"renderer": {"backend": "raster"}} if args.quick else {}
    results["demo_seconds"], results["demo_peak_mb"] = whole_run("demo", raster, repeats)
    paper = {**raster, "camera": {"rate_hz": args.paper_rate_hz}}
    results["paper_seconds"], results["paper_peak_mb"] = whole_run("paper", paper, 1)
    figures = figures_of(results, args.paper_rate_hz, args.quick, (time.perf_counter() - began) / 60, repeats)
    print(f"\nrenderloop benchmarks, {time.strftime('%Y-%m-%d')}, {len(os.sched_getaffinity(0))} cores"
          f"{' (quick: raster runs, one repeat)' if args.quick else ''}")
    for line in figures["table"]["rows"]:
        print("  ".join(str(cell) for cell in line if cell != ""))
    name = args.name or (None if args.quick else "run")
    if name:
        print(save_result(name, figures))


if __name__ == "__main__":
    main()
