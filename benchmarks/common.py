"""What the benchmark scripts share: how repeats are summarised, the scan-like camera pose, and where results go."""

from __future__ import annotations

import argparse
import datetime
import io
import json
import os
import platform
import shlex
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from renderloop.io.atomic import write_bytes, write_text

from renderloop.render.camera import Intrinsics
from renderloop.robot.kinematics import look_at


RESULTS_FOLDER = "RENDERLOOP_BENCHMARK_RESULTS"  # environment: another folder for save_result (run.py reads its children's)
RESULTS = Path(os.environ.get(RESULTS_FOLDER) or Path(__file__).resolve().parent / "results")


# Vector instructions that set ONNX Runtime's and numba's speed: the widest registers (widest first) and the int8
# dot product (VNNI), which ONNX Runtime's int8 kernels use where it exists. A timing compares beside the same set.
SIMD_WIDTHS = ("avx512f", "avx2", "avx", "sse4_2", "asimd")
SIMD_INT8 = ("avx512_vnni", "avx_vnni", "asimddp")


def machine() -> str:
    """The machine a figure was measured on, in words: CPU model, its widest vector instructions, cores this process
    may use, memory."""
    model = platform.processor() or platform.machine()
    try:
        info = Path("/proc/cpuinfo").read_text().splitlines()
        for line in info:
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
        flags = next((set(line.split(":", 1)[1].split()) for line in info if line.startswith(("flags", "Features"))), set())
        simd = [next((w for w in SIMD_WIDTHS if w in flags), None), next((d for d in SIMD_INT8 if d in flags), None)]
        if any(simd):
            model += f" ({', '.join(name for name in simd if name)})"
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
    """Measured records (one dict a case) as the table the docs show: `columns` maps a record's key to its heading; a
    record without a key (a case that gave no figure) shows null there."""
    return {"columns": list(columns.values()), "rows": [[record.get(key) for key in columns] for record in records]}


def save_result(name: str, figures: dict, command: str | None = None) -> Path:
    """Write `benchmarks/results/NAME.json` (or NAME.json in $RENDERLOOP_BENCHMARK_RESULTS): the figures with the date,
    machine, commit and command that measured them.

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


@dataclass(frozen=True)
class Panel:
    """One panel of `plot_against_plants`: its y label, its lines (a table column's heading, the legend's name, a
    matplotlib style: "o-" drawn dark, others light) and an optional target drawn dotted (its value, in words)."""

    label: str
    lines: tuple[tuple[str, str, str], ...]
    target: tuple[float, str] | None = None


def plot_against_plants(results: Path, panels: tuple[Panel, ...], out: Path) -> Path:
    """Draw a stored results file's table against its "plants" column (log x), a panel each, into a small PNG at
    `out`. The picture is drawn only from the results file, so it always shows the figures the docs' table shows."""
    script = f"benchmarks/{results.stem}.py"
    try:
        record = json.loads(results.read_text(encoding="utf-8"))
        table = record["figures"]["table"]
        column = {heading: [row[i] for row in table["rows"]] for i, heading in enumerate(table["columns"])}
        plants = column["plants"]
        series = {heading: column[heading] for panel in panels for heading, _, _ in panel.lines}
    except OSError as error:
        raise SystemExit(f"cannot read {results}: {error.strerror}; run {script} first")
    except (ValueError, KeyError, TypeError, IndexError) as error:
        reason = f"it lacks {error}" if isinstance(error, KeyError) else str(error)
        raise SystemExit(f"{results} is not a {results.stem} results file: {reason}")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    figure, axes = plt.subplots(1, len(panels), figsize=(3 * len(panels), 2.8))
    for axis, panel in zip(axes, panels):
        for heading, name, style in panel.lines:
            axis.plot(plants, series[heading], style, color="#1f3b73" if style == "o-" else "#6b8cc7", label=name,
                      markersize=4)
        top = max(max(series[heading]) for heading, _, _ in panel.lines)
        if panel.target is not None:
            target, said = panel.target
            axis.axhline(target, color="#c0392b", linestyle=":", linewidth=1.2)
            axis.annotate(f"target at {plants[-1]} plants: {said}", (0.03, target), xycoords=("axes fraction", "data"),
                          textcoords="offset points", xytext=(0, -10), fontsize=7, color="#c0392b")
            top = max(top, target)
        axis.set_xscale("log")
        axis.set_xticks(plants, [str(p) for p in plants])
        axis.minorticks_off()
        axis.set_ylim(0, top * 1.1)
        axis.set_xlabel("plants", fontsize=8)
        axis.set_ylabel(panel.label, fontsize=8)
        axis.tick_params(labelsize=7)
        axis.grid(alpha=0.3)
        if len(panel.lines) > 1:
            axis.legend(fontsize=7, loc="center left")
    figure.suptitle(f"Measured {record.get('date', 'unknown')} on {record.get('machine', 'an unknown machine')}", fontsize=7)
    figure.tight_layout()
    drawn = io.BytesIO()
    figure.savefig(drawn, format="png", dpi=110)
    plt.close(figure)
    # A few line colours on white: a 32-colour palette keeps the PNG small without visible loss.
    small = io.BytesIO()
    Image.open(drawn).convert("RGB").quantize(colors=32).save(small, format="PNG", optimize=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_bytes(out, small.getvalue())
    return out


def scaling_arguments(description: str, name: str, panels: tuple[Panel, ...], plot: Path) -> argparse.Namespace | None:
    """The command line of a benchmark measured at several plant counts (--sizes, --no-save), or None once
    --plot-only has redrawn `plot` from the stored results of `name` alone."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--sizes", default="5,40,200,1000", help="plant counts, comma-separated")
    parser.add_argument("--no-save", action="store_true", help="print only; do not write benchmarks/results/")
    parser.add_argument("--plot-only", action="store_true",
                        help=f"measure nothing: redraw {plot.name} from benchmarks/results/{name}.json")
    args = parser.parse_args()
    if args.plot_only:
        print(plot_against_plants(RESULTS / f"{name}.json", panels, plot))
        return None
    return args


def save_and_plot(name: str, figures: dict, panels: tuple[Panel, ...], plot: Path) -> None:
    """`save_result`, then the plot of what it stored (`plot_against_plants`); prints both paths."""
    stored = save_result(name, figures)
    print(stored)
    print(plot_against_plants(stored, panels, plot))
