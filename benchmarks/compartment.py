"""The commercial compartment scanned whole: each line's mission a task, the rows' counts merged, the fleet's schedule.

Runs `renderloop.fleet.compartment.run_compartment` on the `commercial` preset with
benchmarks/configs/compartment.yaml (raster frames at 0.2 Hz) in OUT, on local processes (or
a Ray cluster, --executor ray), and records per line its plants, frames, flight time and ripe
count against the truth, the seconds its stages computed (each row's timings.json: a resumed row keeps its first
run's), the compartment's total with its interval, and the
makespan of the same missions shared by 1 to 4 UAVs (`renderloop.fleet.schedule`, no two in one path
at once). A finished OUT is reused: each row's run is skipped, stage by stage.

    .venv/bin/python benchmarks/compartment.py --out runs/commercial --workers 1
    .venv/bin/python benchmarks/compartment.py --out runs/row1 --workers 1 --config benchmarks/configs/row1.yaml --name compartment_row1
"""

from __future__ import annotations

import argparse
from pathlib import Path

from common import as_table, save_result

from renderloop.config import load_config
from renderloop.fleet.compartment import mission_of, row_dir_of, run_compartment
from renderloop.fleet.schedule import schedule
from renderloop.parallel import Executor
from renderloop.rundir import files, names
from renderloop.rundir.models import DetectionScores

CONFIG = Path(__file__).resolve().parent / "configs" / "compartment.yaml"
COLUMNS = {"row": "line", "plants": "plants", "frames": "frames", "flight_s": "flight s", "compute_s": "computed s",
           "recall": "findable ripe found", "truth": "ripe truth", "estimate": "ripe counted", "error_pct": "error %",
           "interval": "90 % interval"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--executor", default="local")
    parser.add_argument("--config", type=Path, default=CONFIG, help="YAML over the commercial preset.")
    parser.add_argument("--name", default="compartment", help="Results file: benchmarks/results/NAME.json.")
    parser.add_argument("--no-save", action="store_true")
    args = parser.parse_args()
    config = load_config("commercial", args.config)
    run_compartment(args.out, config, executor=Executor.of(args.executor, args.workers))
    merged = files.read_counts(args.out)
    records = []
    for row in merged.rows:
        run_dir = row_dir_of(args.out, row.id)
        part = files.read_counts(run_dir)
        records.append({"row": row.id, "plants": len(part.plants), "frames": part.detections.frames,
                        "flight_s": round(float(files.read_flight(run_dir)["t"][-1]), 1),
                        "compute_s": round(sum(files.read_timings(run_dir).values()), 1),
                        "recall": files.read_model(run_dir / names.DETECTION_SCORES, DetectionScores).ripe_recall,
                        "truth": row.truth,
                        "estimate": row.estimate, "error_pct": part.total.error_pct,
                        "interval": f"{row.interval.low}-{row.interval.high}"})
    total = merged.total
    missions = [mission_of(args.out, config, record["row"]) for record in records]
    makespans = {uavs: schedule(missions, uavs).makespan_s for uavs in range(1, len(missions) + 1)}
    figures = {"table": as_table(records, COLUMNS), "compute_s": round(sum(r["compute_s"] for r in records), 1),
               "workers": args.workers,
               "executor": args.executor, "plants": len(merged.plants),
               "total": {"truth": total.truth, "estimate": total.estimate, "error_pct": total.error_pct,
                         "interval": f"{total.interval.low}-{total.interval.high}", "exact_plants": total.exact_plants,
                         "unripe_truth": total.unripe_truth, "unripe_estimate": total.unripe_estimate},
               "makespan_s": {str(uavs): round(value, 1) for uavs, value in makespans.items()}}
    print(figures)
    if not args.no_save:
        save_result(args.name, figures)


if __name__ == "__main__":
    main()
