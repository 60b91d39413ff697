"""Speed of the Gymnasium environment renderloop/PepperScan-v0: environment steps per second.

Demo preset (one table of 4 plants), raster camera at the demo's 320x240 unless told, a random
policy (seeded), `--episodes` episodes of `--max-views` views; every reset draws a new scene.
A step is one view: the projection of the action, the flight there (MuJoCo, cascade PID,
TOPP-RA), one frame, the detector and the fruit points on it, and the count. Per episode:
the reset's seconds, the mean step's seconds (and its CPU seconds, all threads, which a
busy machine changes less), steps per second (steps alone, and with the reset), and the
simulated flight seconds a step. Median over episodes, with min and max.

    .venv/bin/python benchmarks/gym_env.py [--episodes 3] [--max-views 8] [--width 320 --height 240] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from common import summary

from renderloop.config import Config, load_config
from renderloop.loop.gym_env import PepperScanEnv


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--max-views", type=int, default=8)
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--backend", default="raster", choices=("raster", "cycles"))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()

    data = load_config("demo").model_dump(mode="json")
    data["camera"].update(width=args.width, height=args.height)
    config = Config.model_validate(data)
    rows: dict[str, list[float]] = {"reset_s": [], "step_s": [], "step_cpu_s": [], "steps_per_s": [],
                                    "steps_per_s_with_reset": [], "flight_s_per_step": []}
    start = time.perf_counter()
    with PepperScanEnv(config, backend=args.backend, max_views=args.max_views) as env:
        env.action_space.seed(args.seed)
        first_env = time.perf_counter() - start
        for episode in range(args.episodes):
            before = time.perf_counter()
            env.reset(seed=args.seed if episode == 0 else None)
            reset = time.perf_counter() - before
            steps, flight, done = 0, 0.0, False
            before, cpu = time.perf_counter(), time.process_time()
            while not done:
                _, _, terminated, truncated, info = env.step(env.action_space.sample())
                steps, flight, done = steps + 1, flight + info["flight_time"], terminated or truncated
            stepping, cpu = time.perf_counter() - before, time.process_time() - cpu
            rows["reset_s"].append(reset)
            rows["step_s"].append(stepping / steps)
            rows["step_cpu_s"].append(cpu / steps)
            rows["steps_per_s"].append(steps / stepping)
            rows["steps_per_s_with_reset"].append(steps / (stepping + reset))
            rows["flight_s_per_step"].append(flight / steps)
    results = {name: summary(values) for name, values in rows.items()}
    results.update(environment_construction_s=first_env, cores=len(os.sched_getaffinity(0)), episodes=args.episodes,
                   max_views=args.max_views, camera=[args.width, args.height], backend=args.backend,
                   numpy=np.__version__)
    print(f"gym_env benchmark, demo preset, {args.backend} {args.width}x{args.height}, {results['cores']} cores, "
          f"{args.episodes} episodes of {args.max_views} views (random policy)")
    print(f"{'figure':<28}{'median':>10}{'min':>10}{'max':>10}")
    for name, row in results.items():
        if isinstance(row, dict):
            print(f"{name:<28}{row['median']:>10.2f}{row['min']:>10.2f}{row['max']:>10.2f}")
    print(f"{'environment construction s':<28}{first_env:>10.2f}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
