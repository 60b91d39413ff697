"""The green count's credit for green fruit seen once (`counting.unripe_lone_credit`), fitted on runs and checked on
others.

Takes run directories made by `renderloop run` or `renderloop eval` (an eval folder stands for its seed_* runs), each
with its detections. Each run is counted as `renderloop count` counts it (`count_scan`, the run's own counting
settings), and per plant its green clusters and its lone green detections (`counts.json`'s `unripe_seen_once`: in no
cluster, farther than two eps from every counted green fruit) are kept beside its true green count. --calib RUN...
fits the credit (0 to 1 by 0.05) of the least mean absolute green-yield error of the runs (each run's plants summed;
ties: the most plants exact, then the smaller credit), as benchmarks/intervals.py fits the ripe one; --held RUN...
gives each run's green-yield error with clusters only and at the fitted credit (or --credit).

    .venv/bin/python benchmarks/green_credit.py --calib runs/gh_calib --held runs/gh_eval [--name counting_green_credit]
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from common import save_result

from renderloop.counting.summary import count_scan, run_counting, scanned_rows
from renderloop.counting.uncertainty import credit_of
from renderloop.counting.visibility import fruit_visibility
from renderloop.rundir import files
from renderloop.scene.model import read_scene

CREDITS = tuple(round(0.05 * k, 2) for k in range(21))


@dataclass(frozen=True)
class GreenPlant:
    clusters: int
    lone: int
    truth: int


def run_dirs(paths: list[Path]) -> list[Path]:
    """The runs: each path itself, or an eval folder's seed_* runs."""
    return [run for path in paths for run in ([path] if (path / "detections.json").exists() else sorted(path.glob("seed_*")))]


def green_plants(run: Path) -> list[GreenPlant]:
    config = files.read_config(run)
    times, poses = files.read_poses(run)
    counting = run_counting(config)
    counted = count_scan(read_scene(run), files.read_detections(run, len(times)), poses, counting, config.seed,
                         fruit_visibility(run, len(times)), scanned_rows(config))
    return [GreenPlant(len(plant.unripe_clusters), len(plant.unripe_seen_once), plant.unripe_truth)
            for plant in counted.counts.plants]


def errors(runs: dict[str, list[GreenPlant]], credit: float) -> tuple[dict[str, float], float]:
    """Each run's green-yield error (%, its plants summed) and the share of plants exact, at `credit`."""
    per_run, exact = {}, []
    for run, plants in runs.items():
        estimates = [plant.clusters + credit_of(plant.lone, credit) for plant in plants]
        truth = sum(plant.truth for plant in plants)
        per_run[run] = 100 * (sum(estimates) - truth) / truth
        exact += [estimate == plant.truth for estimate, plant in zip(estimates, plants)]
    return per_run, float(np.mean(exact))


def mean_abs(per_run: dict[str, float]) -> float:
    return float(np.mean(np.abs(list(per_run.values()))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calib", type=Path, nargs="*", default=[], help="runs (or eval folders) to fit on")
    parser.add_argument("--held", type=Path, nargs="*", default=[], help="runs (or eval folders) to check on")
    parser.add_argument("--credit", type=float, help="the credit to check the held runs at (default: the fitted one)")
    parser.add_argument("--name", default="counting_green_credit", help="Results file: benchmarks/results/NAME.json.")
    args = parser.parse_args()
    calib = {str(run): green_plants(run) for run in run_dirs(args.calib)}
    held = {str(run): green_plants(run) for run in run_dirs(args.held)}
    figures: dict = {}
    credit = args.credit
    if calib:
        options = [(c, *errors(calib, c)) for c in CREDITS]
        credit_fit, per_run, exact = min(options, key=lambda option: (mean_abs(option[1]), -option[2], option[0]))
        figures["calibration"] = {"runs": len(calib), "credit": credit_fit, "error_pct": round(mean_abs(per_run), 1),
                                  "error_pct_without": round(mean_abs(options[0][1]), 1),
                                  "lone_per_plant": round(float(np.mean([p.lone for ps in calib.values() for p in ps])), 2)}
        credit = credit_fit if credit is None else credit
    if held and credit is not None:
        without, exact_without = errors(held, 0.0)
        credited, exact = errors(held, credit)
        rows = [[run, sum(p.truth for p in held[run]), round(without[run], 1), round(credited[run], 1)] for run in held]
        rows.append(["mean absolute", sum(row[1] for row in rows), round(mean_abs(without), 1), round(mean_abs(credited), 1)])
        figures["held"] = {"credit": credit, "error_pct": round(mean_abs(credited), 1),
                           "error_pct_without": round(mean_abs(without), 1), "exact_pct": round(100 * exact),
                           "exact_pct_without": round(100 * exact_without),
                           "table": {"columns": ["run", "green fruit", "error, clusters only, %",
                                                 f"error, credit {credit:g}, %"], "rows": rows}}
    for part, values in figures.items():
        print(part, {key: value for key, value in values.items() if key != "table"})
        for row in values.get("table", {}).get("rows", []):
            print("   ", row)
    save_result(args.name, figures)


if __name__ == "__main__":
    main()
