"""Are the ripe-count intervals calibrated? Coverage and width of each plant's interval on rendered runs, and the
fit of the interval model's parameters (renderloop.counting.uncertainty, `counting.interval`).

Takes run directories made by `renderloop run` or `renderloop eval` (an eval folder stands for its seed_* runs).
For each run and each thinning of its scan (--every 1 2 4 8 16: every k-th frame, which is what a camera at rate / k
takes on the same flight, since frames are taken at the instants k / rate_hz), the evidence of every plant (its
clusters in each redraw, their support and view spread, from detections.json and groundtruth.txt) is gathered
once; a set of parameters then costs only the exact distributions. A plant is covered when its true ripe count
(scene.json) lies in its interval; the width is high - low.

--calib RUN... fits weak_real, hidden and hidden_per_lone by grid search on those runs: of the parameters whose
coverage reaches the level at every thinning, those of the smallest mean width (ties: the largest mean log
probability of the true counts). --held RUN... then reports the coverage of the fitted parameters (without
--calib: the config's, or --set's) on runs the fit never saw.

hidden_unseen needs a voxel map, which only an adaptive run has: with --first-pass the runs are adaptive runs, each
plant taken as the mission judged it at its row's first decision (the frames taken before that instant, and the
unseen fraction of its canopy that mission.json recorded then), the interval's other parameters as the run's
`counting.interval`, which the mission decides with; hidden_unseen is fitted alone, the smallest of HIDDEN_UNSEEN
whose coverage reaches the level at every first-pass rate among the runs (the interval widens with it), and the
table gives each value's coverage, mean width and the share of plants the mission would call settled, per rate.

The estimate's credit for fruit seen once (`counting.lone_credit`) is fitted apart, for each thinning: the credit
(0 to 1 by 0.05) of the least mean absolute ripe-yield error of the runs (ties: the most plants exact, then the
smaller credit), since a scan's density decides how often a detection seen once is a real fruit. The tables'
"exact" and "error" are at --lone-credit (default 0, the paper's count).

    .venv/bin/python benchmarks/intervals.py --calib runs/calib --held runs/held [--every 1 2 4 8 16] [--json out.json]

`--credit-only` fits the lone credit alone (no interval, seconds instead of minutes) and checks each thinning's
credit on the held-out runs; with `--result NAME` its table is stored as benchmarks/results/NAME.json for the docs.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from common import save_result

from renderloop.config import IntervalConfig
from renderloop.counting.uncertainty import (
    PlantEvidence,
    central_interval,
    credited,
    evidence,
    plant_pmf,
)
from renderloop.rundir import files
from renderloop.scene.model import read_scene

# The grid: fine where a parameter first widens an interval at 90 % (a weak cluster false with 5 % or more, a Poisson
# of mean 0.0513 or more giving a hidden fruit 5 % of the time), and up to a hidden fruit a plant, for a detector
# that misses many.
GRID = {
    "weak_real": (0.5, 0.6, 0.7, 0.8, 0.9, 0.93, 0.95, 0.97, 0.98, 0.99, 1.0),
    "hidden": (0.0, 0.005, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.075, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.75, 1.0),
    "hidden_per_lone": (0.0, 0.02, 0.04, 0.05, 0.06, 0.075, 0.1, 0.15, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0),
}
CREDITS = tuple(round(0.05 * k, 2) for k in range(21))  # counting.lone_credit, 0 to 1
HIDDEN_UNSEEN = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)


@dataclass(frozen=True)
class Case:
    """One plant of one run, its scan thinned to every `every`-th frame."""

    run: str  # the run directory's path
    every: int
    plant: PlantEvidence
    truth: int  # ripe fruit of the plant in scene.json


def run_dirs(paths: list[Path]) -> list[Path]:
    """Run directories: each path one, or an eval folder of seed_* runs."""
    found = []
    for path in paths:
        if (path / "config.yaml").is_file():
            found.append(path)
        else:
            runs = sorted(p for p in path.glob("seed_*") if (p / "counts.json").is_file())
            if not runs:
                raise SystemExit(f"{path}: neither a counted run directory nor an eval folder of counted runs")
            found += runs
    return found


def gather(run: Path, everies: list[int], interval: IntervalConfig) -> tuple[list[Case], dict[int, float]]:
    """Every plant's evidence at each thinning, and the seconds each took (the redraws' cost)."""
    config = files.read_config(run)
    counting = config.override({"counting": {"interval": interval}}).counting
    scene = read_scene(run)
    times, poses = files.read_poses(run)
    detections = files.read_detections(run, len(times))
    cameras = {index: pose[:3, 3] for index, pose in enumerate(poses)}
    truth = {plant.id: sum(p.ripe for p in scene.peppers_of(plant.id)) for plant in scene.plants}
    cases, seconds = [], {}
    for every in everies:
        frames = [frame for frame in detections.frames if frame.index % every == 0]
        start = time.process_time()
        plants = evidence(scene, frames, cameras, counting, config.seed)
        seconds[every] = time.process_time() - start
        cases += [Case(str(run), every, plants[plant_id], truth[plant_id]) for plant_id in sorted(plants)]
    return cases, seconds


def first_pass(run: Path) -> list[Case]:
    """An adaptive run's plants as its mission judged them at each row's first decision (module docstring); every
    case's `every` is 1."""
    config = files.read_config(run)
    scene = read_scene(run)
    times, poses = files.read_poses(run)
    detections = files.read_detections(run, len(times))
    mission = files.read_mission(run)
    cameras = {index: pose[:3, 3] for index, pose in enumerate(poses)}
    unseen = {plant.id: plant.first_pass.unseen for plant in mission.plants}
    decided = {update.row: update.time for update in mission.harvest if update.round == 0}
    cases = []
    for row, instant in sorted(decided.items()):
        frames = [frame for frame in detections.frames if frame.timestamp <= instant + 1e-9]
        plants = evidence(scene, frames, cameras, config.counting, config.seed, unseen)
        cases += [Case(str(run), 1, plants[plant.id], sum(p.ripe for p in scene.peppers_of(plant.id)))
                  for plant in scene.plants if plant.row == row]
    return cases


def fit_unseen(groups: dict[float, list[Case]], interval: IntervalConfig,
               lone_credit: dict[str, float]) -> tuple[float, list[dict]]:
    """The smallest hidden_unseen of HIDDEN_UNSEEN whose coverage reaches the level in every group (first-pass rate:
    cases), the largest where none does; and per value and group the coverage, mean width and share of plants
    settled (low = high = the estimate with its run's lone credit, `lone_credit`: run path -> credit)."""
    rows = []
    for value in HIDDEN_UNSEEN:
        trial = interval.model_copy(update={"hidden_unseen": value})
        for rate, cases in sorted(groups.items()):
            covered, widths, settled = [], [], []
            for case in cases:
                low, high = central_interval(plant_pmf(case.plant, trial), trial.level)
                covered.append(low <= case.truth <= high)
                widths.append(high - low)
                settled.append(low == high == credited(case.plant, lone_credit[case.run]))
            rows.append({"hidden_unseen": value, "first_pass_rate_hz": rate, "plants": len(cases),
                         "coverage": float(np.mean(covered)), "mean_width": float(np.mean(widths)),
                         "settled": float(np.mean(settled))})
    reached = [value for value in HIDDEN_UNSEEN
               if all(row["coverage"] >= interval.level - 1e-12 for row in rows if row["hidden_unseen"] == value)]
    return (reached[0] if reached else HIDDEN_UNSEEN[-1]), rows


def _shape(plant: PlantEvidence, interval: IntervalConfig) -> tuple:
    """All the model reads of a plant: its strong and weak clusters and lone detections in each draw, and its unseen
    fraction."""
    weak = [sum(cluster.weak(interval) for cluster in draw) for draw in plant.draws]
    return tuple((len(draw) - w, w, lone) for draw, w, lone in zip(plant.draws, weak, plant.lone)), plant.unseen


def yield_error(cases: list[Case], lone_credit: float) -> tuple[float, float]:
    """Mean absolute ripe-yield error of the runs (%, each run's plants summed) and the share of plants exact, with
    the estimate crediting lone detections."""
    runs: dict[str, list[int]] = {}
    exact = []
    for case in cases:
        estimate = credited(case.plant, lone_credit)
        totals = runs.setdefault(case.run, [0, 0])
        totals[0] += estimate
        totals[1] += case.truth
        exact.append(estimate == case.truth)
    errors = [abs(estimate - truth) / truth for estimate, truth in runs.values() if truth]
    return 100 * float(np.mean(errors)) if errors else math.nan, float(np.mean(exact))


def fit_credit(cases: list[Case]) -> dict[int, dict]:
    """Per thinning, the lone credit of the least mean absolute yield error (module docstring)."""
    fitted = {}
    for every in sorted({case.every for case in cases}):
        mine = [case for case in cases if case.every == every]
        options = [(credit, *yield_error(mine, credit)) for credit in CREDITS]
        credit, error, exact = min(options, key=lambda option: (option[1], -option[2], option[0]))
        fitted[every] = {"lone_credit": credit, "error_pct": error, "exact": exact,
                         "error_pct_without": options[0][1], "exact_without": options[0][2]}
    return fitted


def score(cases: list[Case], interval: IntervalConfig, shapes: list[tuple] | None = None,
          lone_credit: float = 0.0) -> dict:
    """Coverage, mean width and mean log probability of the truth, over all cases and per thinning, and the yield
    error at `lone_credit`. Plants of one shape (`_shape`) have one distribution, computed once; `shapes`: the
    cases' shapes, when already known."""
    shapes = shapes if shapes is not None else [_shape(case.plant, interval) for case in cases]
    first = {}
    for case, shape in zip(cases, shapes):
        first.setdefault(shape, case.plant)
    distributions = {}
    for shape, plant in first.items():
        pmf = plant_pmf(plant, interval)
        distributions[shape] = (pmf, *central_interval(pmf, interval.level))
    rows = []
    for case, shape in zip(cases, shapes):
        pmf, low, high = distributions[shape]
        probability = pmf[case.truth] if case.truth < len(pmf) else 0.0
        rows.append((case.every, low <= case.truth <= high, high - low, math.log(max(probability, 1e-300)), case))

    def summary(selected: list[tuple]) -> dict:
        error, exact = yield_error([r[4] for r in selected], lone_credit)
        return {"plants": len(selected), "coverage": float(np.mean([r[1] for r in selected])),
                "mean_width": float(np.mean([r[2] for r in selected])), "log_probability": float(np.mean([r[3] for r in selected])),
                "exact": exact, "error_pct": error}

    everies = sorted({r[0] for r in rows})
    return {"all": summary(rows), "every": {every: summary([r for r in rows if r[0] == every]) for every in everies}}


def fit(cases: list[Case], base: IntervalConfig) -> tuple[IntervalConfig, dict, int]:
    """The grid's smallest mean width with coverage >= level at every thinning; ties: the larger log probability.
    Where no parameters reach the level everywhere, those of the largest worst coverage."""
    best, best_key, tried = None, None, 0
    shapes = [_shape(case.plant, base) for case in cases]  # the grid keeps the weak rule: the shapes stay
    for values in itertools.product(*GRID.values()):
        interval = base.model_copy(update=dict(zip(GRID, values)))
        result = score(cases, interval, shapes)
        tried += 1
        worst = min(part["coverage"] for part in result["every"].values())
        reached = worst >= base.level - 1e-12
        key = (reached, -result["all"]["mean_width"] if reached else worst, result["all"]["log_probability"])
        if best_key is None or key > best_key:
            best, best_key = (interval, result), key
    return best[0], best[1], tried


def print_table(title: str, result: dict, level: float) -> None:
    print(f"\n{title}")
    print(f"{'frames':>10} {'plants':>7} {'exact':>7} {'error':>7} {'coverage':>9} {'mean width':>11} {'log p(truth)':>13}")
    for every, part in [*result["every"].items(), ("all", result["all"])]:
        name = "all" if every == "all" else f"every {every}"
        print(f"{name:>10} {part['plants']:>7} {part['exact']:>7.1%} {part['error_pct']:>6.1f}% {part['coverage']:>9.1%} "
              f"{part['mean_width']:>11.3f} {part['log_probability']:>13.3f}")
    print(f"(level {level:.0%}; exact: share of plants whose estimate is the truth; error: mean absolute ripe-yield "
          "error of the runs)")


def print_credit(title: str, fitted: dict[int, dict]) -> None:
    print(f"\n{title}")
    print(f"{'frames':>10} {'lone credit':>12} {'error':>7} {'exact':>7} {'error at 0':>11} {'exact at 0':>11}")
    for every, part in fitted.items():
        print(f"{'every ' + str(every):>10} {part['lone_credit']:>12.2f} {part['error_pct']:>6.1f}% {part['exact']:>7.1%} "
              f"{part['error_pct_without']:>10.1f}% {part['exact_without']:>11.1%}")


def main_credit(args: argparse.Namespace) -> None:
    """The lone credit alone: fitted per thinning on the calibration runs, each checked on the held-out runs at that
    credit and at 0 (the paper's count). The interval plays no part in an estimate, so it is not fitted."""
    if not args.calib:
        raise SystemExit("--credit-only fits on --calib runs")
    interval = IntervalConfig()
    calib_runs, held_runs = run_dirs(args.calib), run_dirs(args.held)
    calib = [case for run in calib_runs for case in gather(run, args.every, interval)[0]]
    held = [case for run in held_runs for case in gather(run, args.every, interval)[0]]
    fitted = fit_credit(calib)
    print_credit("calibration runs, the estimate's lone credit fitted per thinning", fitted)
    rows = []
    for every, part in fitted.items():
        mine = [case for case in held if case.every == every]
        checked = (*yield_error(mine, part["lone_credit"]), *yield_error(mine, 0.0)) if mine else None
        rows.append(["all" if every == 1 else f"1 in {every}", part["lone_credit"],
                     f"{part['error_pct']:.1f} %, {100 * part['exact']:.0f} % ({part['error_pct_without']:.1f} %, "
                     f"{100 * part['exact_without']:.0f} %)",
                     checked and f"{checked[0]:.1f} %, {100 * checked[1]:.0f} % ({checked[2]:.1f} %, {100 * checked[3]:.0f} %)"])
    if held:
        print("\nheld-out runs at each fitted credit: error, exact (at credit 0)")
        for row in rows:
            print(f"{row[0]:>10} {row[1]:>12.2f}   {row[3]}")
    if args.result:
        table = {"columns": ["frames of the scan", "fitted credit", "calibration: error, exact (credit 0)",
                             "held out: error, exact (credit 0)"], "rows": rows}
        rounded = {str(every): {key: round(value, 1 if key.startswith("error") else 2) for key, value in part.items()}
                   for every, part in fitted.items()}
        figures = {"table": table, "fitted": rounded, "calibration_runs": len(calib_runs), "held_runs": len(held_runs)}
        print("wrote", save_result(args.result, figures))


def main_first_pass(args: argparse.Namespace) -> None:
    report: dict = {}
    for name, paths in (("calib", args.calib), ("held", args.held)):
        if not paths:
            continue
        runs = run_dirs(paths)
        configs = [files.read_config(run) for run in runs]
        if len({config.counting.interval for config in configs}) != 1:
            raise SystemExit(f"{name}: the runs' missions decide with different counting.interval")
        interval, credit = configs[0].counting.interval, {str(run): config.counting.lone_credit for run, config in zip(runs, configs)}
        groups: dict[float, list[Case]] = {}
        for run, config in zip(runs, configs):
            groups.setdefault(config.mission.adaptive.first_pass_rate_hz, []).extend(first_pass(run))
        cases = [case for group in groups.values() for case in group]
        recorded = {(str(run), plant.id): (plant.first_pass.low, plant.first_pass.high)
                    for run in runs for plant in files.read_mission(run).plants}
        agree = sum(recorded[case.run, case.plant.id] == central_interval(plant_pmf(case.plant, interval), interval.level)
                    for case in cases)
        print(f"\n{name}: {len(cases)} plants of {len(runs)} adaptive runs at their first decision; the recomputed "
              f"interval is mission.json's for {agree}")
        value, rows = fit_unseen(groups, interval, credit)
        print(f"{'hidden_unseen':>14} {'first pass Hz':>14} {'plants':>7} {'coverage':>9} {'mean width':>11} {'settled':>8}")
        for row in rows:
            print(f"{row['hidden_unseen']:>14g} {row['first_pass_rate_hz']:>14g} {row['plants']:>7} {row['coverage']:>9.1%} "
                  f"{row['mean_width']:>11.2f} {row['settled']:>8.1%}")
        if name == "calib":
            print(f"fitted: hidden_unseen = {value:g} (level {interval.level:.0%} at every first-pass rate)")
        report[name] = {"runs": [str(run) for run in runs], "rows": rows, "fitted": value if name == "calib" else None}
    if args.json:
        args.json.write_text(json.dumps(report, indent=1) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calib", type=Path, nargs="*", default=[], help="runs (or eval folders) to fit on")
    parser.add_argument("--held", type=Path, nargs="*", default=[], help="runs (or eval folders) to check on")
    parser.add_argument("--every", type=int, nargs="+", default=[1, 2, 4, 8, 16], help="thinnings of each scan")
    parser.add_argument("--set", nargs="*", default=[], metavar="FIELD=VALUE", help="counting.interval fields")
    parser.add_argument("--lone-credit", type=float, default=0.0, help="counting.lone_credit of the tables' estimates")
    parser.add_argument("--first-pass", action="store_true",
                        help="adaptive runs at their first decisions: fit hidden_unseen alone (module docstring)")
    parser.add_argument("--credit-only", action="store_true",
                        help="fit the lone credit per thinning on --calib and check it on --held, without the interval")
    parser.add_argument("--json", type=Path, help="write the figures here too")
    parser.add_argument("--result", metavar="NAME", help="with --credit-only: store its table as benchmarks/results/NAME.json")
    args = parser.parse_args()
    if not args.calib and not args.held:
        parser.error("give --calib runs to fit on, --held runs to check on, or both")
    if args.first_pass:
        main_first_pass(args)
        return
    if args.credit_only:
        main_credit(args)
        return
    base = IntervalConfig.model_validate({**IntervalConfig().model_dump(),
                                          **{k: float(v) if "." in v else int(v) for k, v in (s.split("=", 1) for s in args.set)}})
    report: dict = {"every": args.every, "start": base.model_dump()}

    def cases_of(paths: list[Path], name: str) -> list[Case]:
        cases, costs = [], []
        for run in run_dirs(paths):
            found, seconds = gather(run, args.every, base)
            cases += found
            costs.append(seconds)
            print(f"{name} {run}: " + ", ".join(f"every {k}: {v:.1f} s CPU" for k, v in seconds.items()))
        report[f"{name}_runs"] = [str(run) for run in run_dirs(paths)]
        report[f"{name}_cpu_s"] = {every: float(np.median([c[every] for c in costs])) for every in args.every}
        return cases

    interval = base
    if args.calib:
        calib = cases_of(args.calib, "calib")
        start = time.perf_counter()
        interval, result, tried = fit(calib, base)
        result = score(calib, interval, lone_credit=args.lone_credit)
        print(f"\nfitted on {len(calib)} plant-scans, {tried} parameter sets in {time.perf_counter() - start:.0f} s: "
              + ", ".join(f"{name} = {getattr(interval, name)}" for name in GRID))
        print_table("calibration runs, fitted parameters", result, interval.level)
        print_table("calibration runs, the redraws alone (no hidden fruit, every weak cluster real)",
                    score(calib, interval.model_copy(update={"weak_real": 1.0, "hidden": 0.0, "hidden_per_lone": 0.0})),
                    interval.level)
        report["fitted"] = {name: getattr(interval, name) for name in GRID}
        report["calib"] = result
        report["lone_credit"] = fit_credit(calib)
        print_credit("calibration runs, the estimate's lone credit fitted per thinning", report["lone_credit"])
    if args.held:
        held = cases_of(args.held, "held")
        result = score(held, interval, lone_credit=args.lone_credit)
        print_table("held-out runs, " + ("fitted parameters" if args.calib else "these parameters"), result, interval.level)
        report["held"] = result
    if args.json:
        args.json.write_text(json.dumps(report, indent=1, sort_keys=True, default=str) + "\n")


if __name__ == "__main__":
    main()
