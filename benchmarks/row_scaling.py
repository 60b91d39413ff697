"""What a row's scan costs as the greenhouse grows: the greenhouse preset's layouts of `scene_scaling.py`.

For 5, 40, 200 and 1000 plants (one row of 5, 40 or 200; five rows of 200, the middle one scanned), each in a fresh
process: `renderloop run` of one row (`planner.row`) with raster frames at 0.2 Hz, as `benchmarks/compartment.py`
runs the commercial compartment. Its stages' seconds (timings.json), the frames, the process's wall time and peak
resident memory, and the seconds per scanned plant; and a Cycles frame of the row's middle plant at 320x240 and
1 sample, built for its view (`frame_scaling.py`'s case): its build, frame seconds and peak memory.

    .venv/bin/python benchmarks/row_scaling.py [--sizes 5,40,200,1000] [--no-save]
    .venv/bin/python benchmarks/row_scaling.py --plot-only    # redraw the plot from the stored results

After saving its results to benchmarks/results/row_scaling.json it draws them into docs/images/row_scaling.png.

Target: the seconds per scanned plant and the Cycles frame flat from 40 plants on (a row longer than the camera's
reach), whatever else the greenhouse holds.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml
from common import Panel, as_table, save_and_plot, scaling_arguments
from frame_scaling import run_case
from scene_scaling import MOST_PER_ROW, overrides

ROOT = Path(__file__).resolve().parents[1]
PLOT = ROOT / "docs" / "images" / "row_scaling.png"
SCAN = {"renderer": {"backend": "raster"}, "camera": {"rate_hz": 0.2}}  # compartment.yaml's cost a 2-core machine bears


def layout(plants: int) -> dict:
    """`scene_scaling`'s greenhouse of `plants` plants, its middle row the one scanned."""
    rows = math.ceil(plants / MOST_PER_ROW)
    return {**overrides(plants), **SCAN, "planner": {"row": rows // 2}}


def run_row(config: Path, out: Path) -> dict:
    """`renderloop run` of the row in a fresh process: its wall seconds, peak memory and stage seconds."""
    start = time.perf_counter()
    child = subprocess.Popen([sys.executable, "-m", "renderloop", "run", "--preset", "greenhouse", "--config", str(config),
                              "--out", str(out), "--seed", "0"], cwd=ROOT, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    err = child.stderr.read()
    if os.waitstatus_to_exitcode(status):
        raise SystemExit(f"{config}: renderloop run failed: {err.strip().splitlines()[-1] if err.strip() else ''}")
    timings = json.loads((out / "timings.json").read_text(encoding="utf-8"))
    frames = sum(1 for line in (out / "groundtruth.txt").read_text().splitlines() if line and not line.startswith("#"))
    return {"wall_s": round(wall, 1), "run_rss_mb": round(usage.ru_maxrss / 1024, 1), "frames": frames,
            **{f"{stage}_s": round(seconds, 1) for stage, seconds in timings.items()}}


def measure(plants: int, frame_args: argparse.Namespace) -> dict:
    with tempfile.TemporaryDirectory(prefix="row-scaling-") as tmp:
        config = Path(tmp) / "config.yaml"
        config.write_text(yaml.safe_dump(layout(plants)))
        row = run_row(config, Path(tmp) / "run")
        scanned = plants // math.ceil(plants / MOST_PER_ROW)
        stages = sum(value for key, value in row.items() if key.endswith("_s") and key != "wall_s")
        frame = run_case("greenhouse", "culled", frame_args, config)
    return {"plants": plants, "scanned": scanned, **row, "per_plant_s": round(stages / scanned, 2),
            "cycles_build_s": round(frame["build_s"], 2), "cycles_frame_s": round(frame["frame_s"], 3),
            "cycles_rss_mb": frame["peak_rss_mb"], "cycles_plants": frame["plants"]}


COLUMNS = {"plants": "plants", "scanned": "plants scanned", "frames": "frames", "scene_s": "scene, s", "plan_s": "plan, s",
           "fly_s": "fly, s",
           "render_s": "render, s", "detect_s": "detect, s", "count_s": "count, s", "wall_s": "whole run, s",
           "per_plant_s": "s a plant scanned",
           "run_rss_mb": "peak memory, MB", "cycles_plants": "plants a Cycles frame builds",
           "cycles_frame_s": "Cycles frame, s", "cycles_rss_mb": "Cycles peak memory, MB"}


PANELS = (
    Panel("seconds a plant scanned", ((COLUMNS["per_plant_s"], "whole run", "o-"),)),
    Panel("Cycles frame, s", ((COLUMNS["cycles_frame_s"], "Cycles frame", "o-"),)),
    Panel("peak memory, MB", ((COLUMNS["run_rss_mb"], "the run (raster)", "o-"),
                              (COLUMNS["cycles_rss_mb"], "a Cycles frame", "s--"))),
)


def main() -> None:
    args = scaling_arguments(__doc__.splitlines()[0], "row_scaling", PANELS, PLOT)
    if args is None:
        return
    frame_args = argparse.Namespace(width=320, height=240, samples=1, frames=3)
    table = []
    for plants in (int(size) for size in args.sizes.split(",")):
        table.append(measure(plants, frame_args))
        print(json.dumps(table[-1]), flush=True)
    figures = {"table": as_table(table, COLUMNS), "rate_hz": SCAN["camera"]["rate_hz"],
               "cycles_frame": [frame_args.width, frame_args.height, frame_args.samples]}
    if not args.no_save:
        save_and_plot("row_scaling", figures, PANELS, PLOT)


if __name__ == "__main__":
    main()
