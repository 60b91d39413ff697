"""Count error against frames rendered: static scans at several camera rates beside the adaptive mission.

Reads finished evaluations (`renderloop eval --out DIR`, each of one mission kind and camera rate, on the same
seeds; `DIR,DIR` pools evaluations of one kind made on different seeds) and prints one table, a row per evaluation:
the frames rendered and the flight time per seed, the mean absolute ripe-yield error and the share of plants counted
exactly, from each run's counts.json; `--plot FILE` draws the error and the exact share against frames (static scans
as a line through their rates, the adaptive mission as its own point).

A static scan at a lower rate need not be flown again: `--thin K:CREDIT` adds, for every static evaluation, its scans
thinned to every K-th frame (what a camera at rate / K takes on the same flight: frames are taken at the instants
k / rate_hz), recounted from detections.json with `counting.lone_credit` = CREDIT, the credit fitted for that
thinning on other seeds (benchmarks/intervals.py).

    renderloop eval --preset demo --seeds 21-25 --out runs/static2 --mission static
    renderloop eval --preset demo --seeds 21-25 --out runs/static065 --mission static --config rate065.yaml
    renderloop eval --preset demo --seeds 21-25 --out runs/adaptive --mission adaptive
    .venv/bin/python benchmarks/missions.py runs/static2 runs/static065 runs/adaptive [--thin 2:0.5 4:0.9]
        [--plot curve.png] [--json out.json] [--result NAME --made-by "the eval commands"]

Each row also gives the error with no credit for fruit seen once (the paper's count: a fruit needs two detections),
so what the credit buys stays in sight. `--result NAME` stores the table, a table of every flown evaluation's ripe and
green error per seed and one of how often its plants' 90 % intervals (counts.json) hold the truth, as
benchmarks/results/NAME.json for the docs, with the eval commands that made the folders.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path

from common import save_result
from intervals import gather, run_dirs, yield_error

from renderloop.evaluation.table import scenario, summary
from renderloop.rundir import files


def _point(evaluation: str) -> dict:
    """One evaluation (or several pooled, comma-separated): its mission, camera rate, seeds and summary."""
    runs = run_dirs([Path(part) for part in evaluation.split(",")])
    configs = [files.read_config(run) for run in runs]
    kinds = {config.mission.kind for config in configs}
    if len(kinds) != 1:
        raise SystemExit(f"{evaluation}: one mission kind per evaluation, found {sorted(kinds)}")
    [kind] = kinds
    rate = configs[0].mission.adaptive.first_pass_rate_hz if kind == "adaptive" else configs[0].camera.rate_hz
    scenarios = [scenario(config.seed, kind, run) for config, run in zip(configs, runs)]
    uncredited = [case for config, run in zip(configs, runs) for case in gather(run, [1], config.counting.interval)[0]]
    plants = [plant for run in runs for plant in files.read_counts(run).plants]
    return {"evaluation": evaluation, "mission": kind, "rate_hz": rate, "seeds": sorted(s.seed for s in scenarios),
            "runs": runs, **summary(scenarios), "mean_abs_error_no_credit_pct": round(yield_error(uncredited, 0.0)[0], 2),
            "per_seed": {s.seed: (s.error_pct, s.exact_plants, _green_error(s)) for s in scenarios},
            "plants": len(plants), "plants_without_ripe": sum(p.truth == 0 for p in plants),
            "interval_held": sum(p.interval.low <= p.truth <= p.interval.high for p in plants),
            "interval_width": round(sum(p.interval.high - p.interval.low for p in plants) / len(plants), 2)}


def _green_error(s) -> float | None:
    """A scenario's green-yield error, %: None where the scene bears no green fruit."""
    return round(100 * (s.unripe_estimate - s.unripe_truth) / s.unripe_truth, 1) if s.unripe_truth else None


def _thinned(point: dict, every: int, credit: float) -> dict:
    """A static evaluation's scans thinned to every `every`-th frame, recounted with the lone credit `credit`."""
    cases, frames, errors = [], [], []
    for run in point["runs"]:
        config = files.read_config(run)
        mine = gather(run, [every], config.counting.interval)[0]
        cases += mine
        errors.append((round(yield_error(mine, credit)[0], 2), config.seed))
        frames.append(len(range(0, len(files.read_poses(run)[0]), every)))
    error, exact = yield_error(cases, credit)
    worst = max(errors)
    return {**{k: point[k] for k in ("evaluation", "mission", "seeds", "flight_time_s")}, "rate_hz": point["rate_hz"] / every,
            "every": every, "lone_credit": credit, "frames": sum(frames) / len(frames), "mean_abs_error_pct": round(error, 2),
            "worst_abs_error_pct": worst[0], "worst_seed": worst[1], "exact_plants": round(exact, 4),
            "mean_abs_error_no_credit_pct": round(yield_error(cases, 0.0)[0], 2)}


def _label(point: dict) -> str:
    thinned = f", 1 frame in {point['every']} (lone credit {point['lone_credit']:g})" if "every" in point else ""
    return point["mission"] + thinned


def _per_seed(figures: tuple) -> tuple:
    error, exact, green = figures
    return None if error is None else round(error, 1), round(100 * exact), green


def _result(points: list[dict]) -> dict:
    """The printed table; the flown evaluations' ripe error, plants exact and green error per seed; their intervals."""
    table = {"columns": ["mission", "camera Hz (adaptive: first pass)", "frames a seed", "flight s a seed",
                         "mean abs ripe-yield error, %", "worst seed, %", "plants exact, %",
                         "error without the lone credit, %"],
             "rows": [[_label(p), round(p["rate_hz"], 3), round(p["frames"]), round(p["flight_time_s"]),
                       round(p["mean_abs_error_pct"], 1), f"{p['worst_abs_error_pct']:.1f} (seed {p['worst_seed']})",
                       round(100 * p["exact_plants"]), round(p["mean_abs_error_no_credit_pct"], 1)] for p in points]}
    flown = [p for p in points if "per_seed" in p]
    seeds = {"columns": ["seed", *(f"{_label(p)} at {p['rate_hz']:.2g} Hz: {what}" for p in flown
                                   for what in ("error, %", "plants exact, %", "green error, %"))],
             "rows": [[seed, *(value for p in flown for value in _per_seed(p["per_seed"][seed]))]
                      for seed in flown[0]["seeds"]]}
    intervals = {"columns": ["mission", "camera Hz (adaptive: first pass)", "plants", "of them bearing no ripe fruit",
                             "the 90 % interval holds the truth", "mean width"],
                 "rows": [[_label(p), round(p["rate_hz"], 3), p["plants"], p["plants_without_ripe"], p["interval_held"],
                           p["interval_width"]] for p in flown]}
    return {"table": table, "seeds": seeds, "intervals": intervals}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("evaluations", nargs="+", help="eval folders; DIR,DIR pools folders of one kind")
    parser.add_argument("--thin", nargs="*", default=[], metavar="K:CREDIT",
                        help="also each static evaluation thinned to every K-th frame, counted with lone credit CREDIT")
    parser.add_argument("--plot", type=Path, help="PNG of the error and the exact share against frames.")
    parser.add_argument("--title", default="", help="said beside the seeds above the plot")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--result", metavar="NAME", help="store the tables as benchmarks/results/NAME.json")
    parser.add_argument("--made-by", default="", help="the eval commands that made the folders, for the stored result")
    args = parser.parse_args()
    points = [_point(evaluation) for evaluation in args.evaluations]
    for every, credit in (item.split(":") for item in args.thin):
        points += [_thinned(p, int(every), float(credit)) for p in points if p["mission"] == "static" and "every" not in p]
    seeds = {tuple(p["seeds"]) for p in points}
    if len(seeds) != 1:
        raise SystemExit(f"the evaluations are on different seeds: {sorted(seeds)}")
    points.sort(key=lambda p: (p["mission"], p["frames"]))
    result = _result(points)
    for row in [result["table"]["columns"], ["---"] * len(result["table"]["columns"]), *result["table"]["rows"]]:
        print("| " + " | ".join(map(str, row)) + " |")
    if args.json:
        kept = [{k: v for k, v in p.items() if k not in ("runs", "per_seed")} for p in points]
        args.json.write_text(json.dumps(kept, indent=1))
    if args.result:
        argv = sys.argv[1:]
        if "--made-by" in argv:  # said once, before the command
            del argv[argv.index("--made-by"):argv.index("--made-by") + 2]
        command = shlex.join([".venv/bin/python", "benchmarks/missions.py", *argv])
        print("wrote", save_result(args.result, result, f"{args.made_by}; {command}" if args.made_by else command))
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        figure, axes = plt.subplots(1, 2, figsize=(9, 3.4))
        for key, axis, label in (("mean_abs_error_pct", axes[0], "mean absolute ripe-yield error, %"),
                                 ("exact_plants", axes[1], "share of plants counted exactly")):
            static = sorted((p for p in points if p["mission"] == "static"), key=lambda p: p["frames"])
            axis.plot([p["frames"] for p in static], [p[key] for p in static], "o-", color="#1f3b73", label="static scan")
            thinned = [p for p in static if "every" in p]
            axis.plot([p["frames"] for p in thinned], [p[key] for p in thinned], "o", color="#1f3b73", markerfacecolor="white",
                      label="the same, thinned" if thinned else None)
            for p in static:
                axis.annotate(f"{p['rate_hz']:.2g} Hz", (p["frames"], p[key]), textcoords="offset points", xytext=(4, 4), fontsize=8)
            adaptive = [p for p in points if p["mission"] == "adaptive"]
            axis.plot([p["frames"] for p in adaptive], [p[key] for p in adaptive], "D", color="#e67e22", markersize=8,
                      label="adaptive mission (first pass at)")
            for i, p in enumerate(adaptive):  # labels alternate below and above, so that near points keep theirs apart
                axis.annotate(f"{p['rate_hz']:.2g} Hz", (p["frames"], p[key]), textcoords="offset points", xytext=(4, -12 if i % 2 == 0 else 7),
                              fontsize=8, color="#e67e22")
            axis.set_xlabel("frames rendered a seed")
            axis.set_ylabel(label)
            axis.grid(alpha=0.3)
            axis.margins(x=0.08, y=0.15)
        axes[0].legend(fontsize=8)
        figure.suptitle(f"seeds {', '.join(map(str, points[0]['seeds']))}" + (args.title and f": {args.title}"), fontsize=9)
        figure.tight_layout()
        figure.savefig(args.plot, dpi=110)


if __name__ == "__main__":
    main()
