"""Count error against frames rendered: static scans at several camera rates beside the adaptive mission.

Reads finished evaluations (`renderloop eval --out DIR`, each of one mission kind and camera rate, on the same
seeds) and prints one table, a row per evaluation: the frames rendered and the flight time per seed, the mean
absolute ripe-yield error and the share of plants counted exactly; `--plot FILE` draws the error and the exact share
against frames (static scans as a line through their rates, the adaptive mission as its own point).

    renderloop eval --preset demo --seeds 21-25 --out runs/static2 --mission static
    renderloop eval --preset demo --seeds 21-25 --out runs/static065 --mission static --config rate065.yaml
    renderloop eval --preset demo --seeds 21-25 --out runs/adaptive --mission adaptive
    .venv/bin/python benchmarks/missions.py runs/static2 runs/static065 runs/adaptive [--plot curve.png] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from renderloop.evaluation.table import EVAL_JSON, Scenario, summary
from renderloop.rundir import files


def _point(directory: Path) -> dict:
    scenarios = [Scenario(**row) for row in json.loads((directory / EVAL_JSON).read_text())["scenarios"]]
    kinds = {s.mission for s in scenarios}
    if len(kinds) != 1:
        raise SystemExit(f"{directory}: one mission kind per evaluation, found {sorted(kinds)}")
    [kind] = kinds
    runs = [p for p in directory.iterdir() if p.is_dir() and p.name.startswith("seed_")]
    config = files.read_config(runs[0])
    rate = config.mission.adaptive.first_pass_rate_hz if kind == "adaptive" else config.camera.rate_hz
    return {"evaluation": str(directory), "mission": kind, "rate_hz": rate, "seeds": sorted(s.seed for s in scenarios),
            **summary(scenarios)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("evaluations", nargs="+", type=Path)
    parser.add_argument("--plot", type=Path, help="PNG of the error and the exact share against frames.")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    points = [_point(directory) for directory in args.evaluations]
    seeds = {tuple(p["seeds"]) for p in points}
    if len(seeds) != 1:
        raise SystemExit(f"the evaluations are on different seeds: {sorted(seeds)}")
    print("| mission | camera Hz (adaptive: first pass) | frames a seed | flight s a seed | mean abs error % | plants exact |")
    print("| --- | --- | --- | --- | --- | --- |")
    for p in sorted(points, key=lambda p: (p["mission"], p["frames"])):
        print(f"| {p['mission']} | {p['rate_hz']:g} | {p['frames']:g} | {p['flight_time_s']:g} | "
              f"{p['mean_abs_error_pct']:.1f} | {p['exact_plants']:.0%} |")
    if args.json:
        args.json.write_text(json.dumps(points, indent=1))
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        figure, axes = plt.subplots(1, 2, figsize=(9, 3.4))
        for key, axis, label in (("mean_abs_error_pct", axes[0], "mean absolute ripe-yield error, %"),
                                 ("exact_plants", axes[1], "share of plants counted exactly")):
            static = sorted((p for p in points if p["mission"] == "static"), key=lambda p: p["frames"])
            axis.plot([p["frames"] for p in static], [p[key] for p in static], "o-", color="#1f3b73", label="static scan")
            for p in static:
                axis.annotate(f"{p['rate_hz']:g} Hz", (p["frames"], p[key]), textcoords="offset points", xytext=(4, 4), fontsize=8)
            adaptive = [p for p in points if p["mission"] == "adaptive"]
            axis.plot([p["frames"] for p in adaptive], [p[key] for p in adaptive], "D", color="#e67e22", markersize=8,
                      label="adaptive mission (first pass at)")
            for p in adaptive:
                axis.annotate(f"{p['rate_hz']:g} Hz", (p["frames"], p[key]), textcoords="offset points", xytext=(4, -12),
                              fontsize=8, color="#e67e22")
            axis.set_xlabel("frames rendered a seed")
            axis.set_ylabel(label)
            axis.grid(alpha=0.3)
        axes[0].legend(fontsize=8)
        figure.suptitle(f"seeds {', '.join(map(str, points[0]['seeds']))}", fontsize=9)
        figure.tight_layout()
        figure.savefig(args.plot, dpi=110)


if __name__ == "__main__":
    main()
