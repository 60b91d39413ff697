"""What the benchmark scripts share: how repeats are summarised, the scan-like camera pose, and where results go."""

from __future__ import annotations

import datetime
import json
import os
import platform
import shlex
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from renderloop.io.atomic import write_text

from renderloop.render.camera import Intrinsics
from renderloop.robot.kinematics import look_at


RESULTS = Path(__file__).resolve().parent / "results"


def machine() -> str:
    """The machine a figure was measured on, in words: CPU model, cores this process may use, memory."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
        memory_kb = next(int(line.split()[1]) for line in Path("/proc/meminfo").read_text().splitlines() if line.startswith("MemTotal"))
        memory = f", {memory_kb / 2**20:.0f} GiB"
    except (OSError, StopIteration, ValueError):
        memory = ""
    return f"{model}, {len(os.sched_getaffinity(0))} cores{memory}, {platform.system()} {platform.release()}"


def commit() -> str:
    """The repository's commit, with `+dirty` when the working tree differs from it."""
    root = Path(__file__).resolve().parents[1]
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root, capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+dirty" if dirty else "")


def as_table(records: list[dict], columns: dict[str, str]) -> dict:
    """Measured records (one dict a case) as the table the docs show: `columns` maps a record's key to its heading."""
    return {"columns": list(columns.values()), "rows": [[record[key] for key in columns] for record in records]}


def save_result(name: str, figures: dict, command: str | None = None) -> Path:
    """Write `benchmarks/results/NAME.json`: the figures with the date, machine, commit and command that measured them.

    The docs render their tables from these files (docs/hooks/results.py), so a figure is measured
    once and shown from one place. `command` defaults to how this process was started.
    """
    if command is None:
        command = shlex.join([".venv/bin/python", os.path.relpath(sys.argv[0], Path(__file__).resolve().parents[1]), *sys.argv[1:]])
    record = {
        "name": name,
        "date": datetime.date.today().isoformat(),
        "machine": machine(),
        "commit": commit(),
        "command": command,
        "figures": figures,
    }
    path = RESULTS / f"{name}.json"
    RESULTS.mkdir(exist_ok=True)
    write_text(path, json.dumps(record, indent=1, sort_keys=True) + "\n")
    return path


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
