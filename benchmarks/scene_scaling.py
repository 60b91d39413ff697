"""How `renderloop scene` scales with the number of plants: the greenhouse preset's row made longer.

For 5, 40, 200 and 1000 plants of the greenhouse preset ('highwire' plants in the film greenhouse, its 8 plant
prototypes), each size in a fresh process (so no library or import is shared, and its peak memory is its own): the
scene stage's wall time (generate, world.xml checked by MuJoCo, top view, scene.json), the whole process's wall
time and peak resident memory, and the sizes of scene.json and world.xml. A row holds at most 200 plants
(`MAX_PLANTS_PER_TABLE`, and a room side at most 200 m): 1000 plants stand in five rows of 200, 3.4 m apart,
each with the aisles the preset's single row has.

    .venv/bin/python benchmarks/scene_scaling.py [--sizes 5,40,200,1000] [--no-save]
    .venv/bin/python benchmarks/scene_scaling.py --plot-only    # redraw the plot from the stored results

Targets: 1000 plants within 60 s and 1 GB on 2 cores; 40 plants within 1.5 times the time of 5; scene.json under
5 MB at 1000 plants. After saving its results to benchmarks/results/scene_scaling.json it draws them, with the
targets, into docs/images/scene_scaling.png; `--plot-only` redraws that picture from the stored results alone.
"""

from __future__ import annotations

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


ROOT = Path(__file__).resolve().parents[1]
ROW_PITCH = 3.4  # m: the greenhouse preset's compartment is this wide round its one row
MOST_PER_ROW = 200
SPACING = 0.5  # m: the preset's plant spacing
ENDS = 3.9  # m of room beyond a row's plants: the preset's 6.4 m room round its 2.5 m row
PLOT = ROOT / "docs" / "images" / "scene_scaling.png"
TARGET_S, TARGET_MB, TARGET_JSON_MB = 60.0, 1000.0, 5.0  # at 1000 plants: the docstring's targets

CHILD = """
import json, sys, time
from pathlib import Path
start = time.perf_counter()
from renderloop.config import load_config
from renderloop.scene.stage import run_scene
imported = time.perf_counter()
config = load_config("greenhouse", Path(sys.argv[1]), seed=0)
run_scene(Path(sys.argv[2]), config)
print(json.dumps({"import_s": imported - start, "stage_s": time.perf_counter() - imported}))
"""


def overrides(plants: int) -> dict:
    rows = math.ceil(plants / MOST_PER_ROW)
    per_row = plants // rows
    if per_row * rows != plants:
        raise SystemExit(f"{plants} plants do not split evenly into rows of at most {MOST_PER_ROW}")
    length = per_row * SPACING
    width, depth = rows * ROW_PITCH, length + ENDS
    xs = [(k - (rows - 1) / 2) * ROW_PITCH for k in range(rows)]
    return {"greenhouse": {
        "size": [width, depth, 3.0], "tables": [[x, 0.0] for x in xs], "table_size": [0.3, length, 0.1],
        "plants_per_table": per_row, "workstation_center": [xs[0], -depth / 2 + 0.35]}}


def measure(plants: int) -> dict:
    with tempfile.TemporaryDirectory(prefix="scene-scaling-") as tmp:
        config, run_dir = Path(tmp) / "config.yaml", Path(tmp) / "run"
        config.write_text(yaml.safe_dump(overrides(plants)))
        start = time.perf_counter()
        child = subprocess.Popen([sys.executable, "-c", CHILD, str(config), str(run_dir)], cwd=ROOT,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - start
        out, err = child.stdout.read(), child.stderr.read()
        child.returncode = os.waitstatus_to_exitcode(status)
        if child.returncode:
            raise SystemExit(f"{plants} plants: the scene stage failed: {err.strip().splitlines()[-1] if err.strip() else out}")
        timings = json.loads(out.strip().splitlines()[-1])
        scene = json.loads((run_dir / "scene.json").read_text())
        return {
            "plants": plants, "rows": len(scene["rows"]), "prototypes": len(scene.get("prototypes") or []),
            "peppers": len(scene["peppers"]), "stage_s": round(timings["stage_s"], 2), "process_s": round(wall, 2),
            "peak_rss_mb": round(usage.ru_maxrss / 1024, 1),
            "scene_json_mb": round((run_dir / "scene.json").stat().st_size / 1e6, 3),
            "world_xml_mb": round((run_dir / "world.xml").stat().st_size / 1e6, 3),
            "load_1min": round(os.getloadavg()[0], 2),
        }


COLUMNS = {"plants": "plants", "rows": "rows", "prototypes": "prototypes (0: each grown)", "peppers": "fruit",
           "stage_s": "scene stage, s", "process_s": "whole process, s", "peak_rss_mb": "peak memory, MB",
           "scene_json_mb": "scene.json, MB", "world_xml_mb": "world.xml, MB", "load_1min": "machine load"}


PANELS = (
    Panel("seconds", ((COLUMNS["stage_s"], "scene stage", "o-"), (COLUMNS["process_s"], "whole process", "s--")),
          (TARGET_S, "60 s")),
    Panel("peak memory, MB", ((COLUMNS["peak_rss_mb"], "peak memory", "o-"),), (TARGET_MB, "1 GB")),
    Panel("scene.json, MB", ((COLUMNS["scene_json_mb"], "scene.json", "o-"),), (TARGET_JSON_MB, "5 MB")),
)


def main() -> None:
    args = scaling_arguments(__doc__.splitlines()[0], "scene_scaling", PANELS, PLOT)
    if args is None:
        return
    table = []
    for plants in (int(size) for size in args.sizes.split(",")):
        table.append(measure(plants))
        print(json.dumps(table[-1]), flush=True)
    by_size = {row["plants"]: row for row in table}
    figures = {"table": as_table(table, COLUMNS), "cores": len(os.sched_getaffinity(0))}
    if 5 in by_size and 40 in by_size:
        figures["stage_40_over_5"] = round(by_size[40]["stage_s"] / by_size[5]["stage_s"], 2)
        figures["process_40_over_5"] = round(by_size[40]["process_s"] / by_size[5]["process_s"], 2)
    print(json.dumps({key: value for key, value in figures.items() if key != "table"}))
    if not args.no_save:
        save_and_plot("scene_scaling", figures, PANELS, PLOT)


if __name__ == "__main__":
    main()
