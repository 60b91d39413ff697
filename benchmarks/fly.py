"""Speed of `renderloop fly` on one core: real-time factor and physics steps per second.

Measured side by side in one run on the paper preset: MuJoCo stepping the world with
the rotors at hover (physics alone), and the whole closed loop (cascade PID at 100 Hz,
logging included). Reference: 1x real time (Gazebo/RotorS runs at about 1x).
Median over repeats, with min and max.

    .venv/bin/python benchmarks/fly.py [--repeats 3] [--seconds 60] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
from common import summary

from renderloop.config import load_config
from renderloop.io.csvtable import read_csv
from renderloop.planning.stage import run_plan
from renderloop.planning.trajectory import HEADER
from renderloop.scene.stage import run_scene
from renderloop.sim.flight import Reference, fly


def physics_only(model: mujoco.MjModel, hover_ctrl: float, seconds: float) -> float:
    data = mujoco.MjData(model)
    data.qpos[:3] = (0.0, -1.2, 1.0)
    data.ctrl[:4] = hover_ctrl
    steps = int(seconds / model.opt.timestep)
    start = time.perf_counter()
    mujoco.mj_step(model, data, nstep=steps)
    return steps / (time.perf_counter() - start)


def closed_loop(model: mujoco.MjModel, config, reference: Reference) -> float:
    start = time.perf_counter()
    log = fly(model, config, reference, hold=0.0)
    return log.t[-1] / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per repeat")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core

    config = load_config("paper", seed=7)
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp)
        run_scene(run_dir, config)
        run_plan(run_dir, config)
        table = read_csv(run_dir / "trajectory.csv", HEADER)
        model = mujoco.MjModel.from_xml_path(str(run_dir / "world.xml"))
    count = min(len(table), int(args.seconds * config.planner.sample_rate_hz) + 1)
    reference = Reference(table[:count, 0], table[:count, 1:8], table[:count, 8:15], table[:count, 15:22])
    uav = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "uav")
    hover = 9.81 * float(model.body_subtreemass[uav]) / (4 * config.robot.rotor.kf)  # w² at hover

    physics = [physics_only(model, hover, args.seconds) for _ in range(args.repeats)]
    factor = [closed_loop(model, config, reference) for _ in range(args.repeats)]
    steps_per_control = 1.0 / (config.controller.rate_hz * config.controller.physics_dt)
    results = {
        "physics_steps_per_s": summary(physics),
        "physics_real_time_factor": summary([p * config.controller.physics_dt for p in physics]),
        "closed_loop_real_time_factor": summary(factor),
        "closed_loop_physics_steps_per_s": summary([f / config.controller.physics_dt for f in factor]),
        "reference_real_time_factor": 1.0,
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "simulated_seconds": float(reference.t[-1]),
        "physics_steps_per_control_tick": steps_per_control,
    }
    print(f"fly benchmark, paper preset, one core, {args.repeats} repeats of {reference.t[-1]:.0f} s simulated")
    print(f"{'figure':<40}{'median':>12}{'min':>12}{'max':>12}")
    for name in ("physics_steps_per_s", "physics_real_time_factor", "closed_loop_physics_steps_per_s", "closed_loop_real_time_factor"):
        row = results[name]
        print(f"{name:<40}{row['median']:>12.1f}{row['min']:>12.1f}{row['max']:>12.1f}")
    print(f"{'reference (Gazebo/RotorS) real-time factor':<40}{1.0:>12.1f}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
