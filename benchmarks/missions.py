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
        [--plot curve.png] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

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
    return {"evaluation": evaluation, "mission": kind, "rate_hz": rate, "seeds": sorted(s.seed for s in scenarios),
            "runs": runs, **summary(scenarios)}


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
            "worst_abs_error_pct": worst[0], "worst_seed": worst[1], "exact_plants": round(exact, 4)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("evaluations", nargs="+", help="eval folders; DIR,DIR pools folders of one kind")
    parser.add_argument("--thin", nargs="*", default=[], metavar="K:CREDIT",
                        help="also each static evaluation thinned to every K-th frame, counted with lone credit CREDIT")
    parser.add_argument("--plot", type=Path, help="PNG of the error and the exact share against frames.")
    parser.add_argument("--title", default="", help="said beside the seeds above the plot")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    points = [_point(evaluation) for evaluation in args.evaluations]
    for every, credit in (item.split(":") for item in args.thin):
        points += [_thinned(p, int(every), float(credit)) for p in points if p["mission"] == "static" and "every" not in p]
    seeds = {tuple(p["seeds"]) for p in points}
    if len(seeds) != 1:
        raise SystemExit(f"the evaluations are on different seeds: {sorted(seeds)}")
    print("| mission | camera Hz (adaptive: first pass) | frames a seed | flight s a seed | mean abs error % | plants exact |")
    print("| --- | --- | --- | --- | --- | --- |")
    for p in sorted(points, key=lambda p: (p["mission"], p["frames"])):
        thinned = f" (1 frame in {p['every']}, lone credit {p['lone_credit']:g})" if "every" in p else ""
        print(f"| {p['mission']}{thinned} | {p['rate_hz']:.2g} | {p['frames']:g} | {p['flight_time_s']:g} | "
              f"{p['mean_abs_error_pct']:.1f} | {p['exact_plants']:.0%} |")
    if args.json:
        args.json.write_text(json.dumps([{k: v for k, v in p.items() if k != "runs"} for p in points], indent=1))
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
