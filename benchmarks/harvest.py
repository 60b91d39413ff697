"""What the harvest plan's 2-opt costs: the vectorised move search against the pair-by-pair scan it replaces.

For 52, 208 and 1000 stops, on two layouts: `uniform`, stops drawn uniformly in a 20 m square with the workstation
0.5 m beyond the middle of one side; `rows`, the commercial preset's four plant lines (x = -1.35, -0.95, 0.95,
1.35 m, a plant every 0.38 m), long enough that the stops are two in three of their plants, drawn at random, with
the workstation 0.6 m before the lines' start: reversals there often tie. Each instance (seeded, `--instances` of
each layout and size) starts from the nearest-neighbour tour and is improved by both implementations of
`renderloop.counting.harvest` in this process: `two_opt_pair_by_pair` (the scan that tests one reversal at a time
with numpy's norm of each leg, as `two_opt` did before its search was vectorised) once, the vectorised `two_opt`
`--repeats` times. Reported per layout and size: the median over instances of each one's seconds (the vectorised
one's median of its repeats) and of the greedy tour's, the speed-up, whether every tour is the same, and how much
2-opt shortens the greedy tour.

    .venv/bin/python benchmarks/harvest.py [--sizes 52,208,1000] [--instances 3] [--repeats 5] [--no-save]

Target: 1000 stops in about a second (the pair-by-pair scan takes about 20 s), the same tours as the scan.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time

import numpy as np
from common import as_table, save_result

from renderloop.counting.harvest import (
    nearest_neighbour,
    tour_length,
    two_opt,
    two_opt_pair_by_pair,
)

SIDE = 20.0  # m: the uniform layout's square
LINES = (-1.35, -0.95, 0.95, 1.35)  # m: the commercial preset's plant lines
SPACING = 0.38  # m: its plants along a line


def instance(layout: str, size: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The workstation and the stops of one instance."""
    if layout == "uniform":
        rng = np.random.default_rng([size, seed])
        return np.array([0.0, -SIDE / 2 - 0.5]), rng.uniform(-SIDE / 2, SIDE / 2, size=(size, 2))
    per_line = -(-3 * size // (2 * len(LINES)))  # two in three of the lines' plants are stops
    grid = np.array([[x, k * SPACING] for x in LINES for k in range(per_line)])
    rng = np.random.default_rng([size, seed, 1])
    return np.array([0.0, -0.6]), grid[np.sort(rng.choice(len(grid), size=size, replace=False))]


def timed(function, *args) -> tuple[list[int], float]:
    begin = time.perf_counter()
    result = function(*args)
    return result, time.perf_counter() - begin


def measure(layout: str, size: int, instances: int, repeats: int) -> dict:
    greedy_s, old_s, new_s, same, shortened = [], [], [], True, []
    for seed in range(instances):
        start, stops = instance(layout, size, seed)
        greedy, seconds = timed(nearest_neighbour, start, stops)
        greedy_s.append(seconds)
        old, seconds = timed(two_opt_pair_by_pair, start, stops, greedy)
        old_s.append(seconds)
        runs = [timed(two_opt, start, stops, greedy) for _ in range(repeats)]
        new_s.append(statistics.median(seconds for _, seconds in runs))
        same = same and all(new == old for new, _ in runs)
        greedy_length = tour_length(start, stops, greedy)
        shortened.append(100 * (greedy_length - tour_length(start, stops, runs[0][0])) / greedy_length)
    old_median, new_median = statistics.median(old_s), statistics.median(new_s)
    return {"layout": layout, "stops": size, "instances": instances,
            "greedy_s": round(statistics.median(greedy_s), 4), "old_s": round(old_median, 4), "new_s": round(new_median, 4), "speedup": round(old_median / new_median, 1),
            "same_tours": same, "shortened_pct": round(statistics.median(shortened), 1),
            "load_1min": round(os.getloadavg()[0], 2)}


COLUMNS = {"layout": "layout", "stops": "stops", "instances": "instances", "greedy_s": "nearest neighbour, s",
           "old_s": "pair-by-pair scan, s",
           "new_s": "vectorised, s", "speedup": "speed-up", "same_tours": "same tours",
           "shortened_pct": "2-opt shortens greedy by, %", "load_1min": "machine load"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="52,208,1000", help="stop counts, comma-separated")
    parser.add_argument("--instances", type=int, default=3, help="seeded instances of each layout and size")
    parser.add_argument("--repeats", type=int, default=5, help="timings of the vectorised search per instance")
    parser.add_argument("--no-save", action="store_true", help="print only; do not write benchmarks/results/")
    args = parser.parse_args()
    try:
        sizes = [int(size) for size in args.sizes.split(",")]
    except ValueError:
        raise SystemExit(f"--sizes: expected comma-separated whole numbers, got {args.sizes!r}") from None
    if min(sizes) < 1 or args.instances < 1 or args.repeats < 1:
        raise SystemExit("--sizes, --instances and --repeats must be at least 1")
    table = []
    for layout in ("uniform", "rows"):
        for size in sizes:
            table.append(measure(layout, size, args.instances, args.repeats))
            print(json.dumps(table[-1]), flush=True)
    figures = {"table": as_table(table, COLUMNS), "cores": len(os.sched_getaffinity(0)),
               "same_tours": all(row["same_tours"] for row in table)}
    for row in table:
        figures[f"{row['layout']}_{row['stops']}"] = {key: row[key] for key in ("old_s", "new_s", "speedup")}
    print(json.dumps({key: value for key, value in figures.items() if key != "table"}))
    if not args.no_save:
        print(save_result("harvest", figures))


if __name__ == "__main__":
    main()
