"""Speed of `renderloop fly` on one core: real-time factor, physics steps per second, controller cost per tick.

Measured side by side in one run on the paper preset: MuJoCo stepping the world with
the rotors at hover (physics alone); the whole closed loop (cascade PID at 100 Hz,
logging included) over the first --seconds of the scan; one control tick split into
its controller (Flight.tick with its physics steps made no-ops, at states met
along that flight) and its physics (the same states, stepped); and the whole
`renderloop fly` process on the whole scan (interpreter start, imports, flight,
flight.csv, groundtruth.txt and plots), the figure issue 23 asks to be at least 100x, and
its parts: the interpreter's start and its imports, reading the trajectory, the flight,
writing flight.csv and drawing the two figures.
The compiled controller's cache is warm by then (the flights in this process fill it;
a first flight after an install or an edit of robot/kernel.py compiles it, seconds).
Reference: 1x real time (Gazebo/RotorS runs at about 1x). Median over repeats, with
min and max.

    .venv/bin/python benchmarks/fly.py [--repeats 3] [--seconds 60] [--process-repeats 3] [--name fly_speed]
        [--json out.json]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
import types
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np
from common import save_result, summary

import renderloop.sim.flight as flight_module
from renderloop.config import Config, load_config
from renderloop.io.csvtable import read_csv
from renderloop.planning.stage import run_plan
from renderloop.rundir.files import TRAJECTORY_HEADER
from renderloop.rundir.files import FLIGHT_HEADER
from renderloop.scene.stage import run_scene
from renderloop.sim.flight import Flight, Reference, fly, resample

STATE_EVERY_S = 2.0  # the controller is timed at the flight's state every this many simulated seconds
TICKS_PER_STATE = 20

# `renderloop fly RUN_DIR --force` in a process of its own, each part timed where the fly stage calls it (a part
# called twice counts twice); last it prints when its imports were done (epoch seconds, for the parent to count the
# interpreter's start in) and the parts' seconds, as JSON.
TIMED_FLY = """
import json, sys, time

import renderloop.cli
import renderloop.sim.stage as stage

imported, parts = time.time(), {}


def timed(part, function):
    def call(*args, **kwargs):
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            parts[part] = parts.get(part, 0.0) + time.perf_counter() - start
    return call


stage.files.read_trajectory = timed("trajectory", stage.files.read_trajectory)
stage.fly_in_corridor = timed("flight", stage.fly_in_corridor)
stage.files.write_flight = timed("flight_csv", stage.files.write_flight)
stage.draw_flight_paths = timed("figures", stage.draw_flight_paths)
stage.draw_tracking_error = timed("figures", stage.draw_tracking_error)
sys.argv = ["renderloop", "fly", sys.argv[1], "--force"]
try:
    renderloop.cli.main()
finally:
    print(json.dumps({"imported": imported, **parts}))
"""
PARTS = ("imports", "trajectory", "flight", "flight_csv", "figures")


def physics_only(model: mujoco.MjModel, hover_ctrl: float, seconds: float) -> float:
    data = mujoco.MjData(model)
    data.qpos[:3] = (0.0, -1.2, 1.0)
    data.ctrl[:4] = hover_ctrl
    steps = int(seconds / model.opt.timestep)
    start = time.perf_counter()
    mujoco.mj_step(model, data, nstep=steps)
    return steps / (time.perf_counter() - start)


def closed_loop(model: mujoco.MjModel, config: Config, reference: Reference) -> float:
    start = time.perf_counter()
    log = fly(model, config, reference, hold=0.0)
    return log.t[-1] / (time.perf_counter() - start)


def _skip(*args, **kwargs) -> None:
    return None


@contextlib.contextmanager
def no_physics() -> Iterator[None]:
    """`mujoco` as renderloop.sim.flight sees it, but with the physics steps doing nothing: Flight.tick is then
    the controller alone (mju_quat2Mat and mj_fullM, which it calls for its inputs, included)."""
    skipped = {name: _skip for name in ("mj_step", "mj_step1", "mj_step2", "mj_forward")}
    flight_module.mujoco = types.SimpleNamespace(**{**vars(mujoco), **skipped})
    try:
        yield
    finally:
        flight_module.mujoco = mujoco


def flight_states(model: mujoco.MjModel, config: Config, reference: Reference) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """(tick, qpos, qvel) every STATE_EVERY_S along the closed-loop flight of `reference`."""
    ticks = resample(reference, config.controller.rate_hz, 0.0)
    flight = Flight(model, config, config.seed)
    flight.reset(ticks.q[0])
    every = round(STATE_EVERY_S * config.controller.rate_hz)
    states = []
    for k in range(len(ticks.t)):
        if k % every == 0:
            states.append((k, flight.data.qpos.copy(), flight.data.qvel.copy()))
        flight.tick(ticks.q[k], ticks.qd[k], ticks.qdd[k])
    return states


def tick_split(model: mujoco.MjModel, config: Config, reference: Reference, states: list) -> tuple[float, float]:
    """Microseconds per control tick: the controller alone, and the physics (the substeps, split as Flight.tick splits them)."""
    ticks = resample(reference, config.controller.rate_hz, 0.0)
    flight = Flight(model, config, config.seed)
    flight.reset(ticks.q[0])
    data, substeps = flight.data, flight.substeps
    controller = physics = 0.0
    for k, qpos, qvel in states:
        q, qd, qdd = ticks.q[k], ticks.qd[k], ticks.qdd[k]
        data.qpos[:], data.qvel[:] = qpos, qvel
        mujoco.mj_forward(model, data)
        with no_physics():
            start = time.perf_counter()
            for _ in range(TICKS_PER_STATE):
                flight.tick(q, qd, qdd)
            controller += time.perf_counter() - start
        start = time.perf_counter()
        for _ in range(TICKS_PER_STATE):  # with the controls that tick left
            mujoco.mj_step2(model, data)
            mujoco.mj_step(model, data, nstep=substeps - 1)
            mujoco.mj_step1(model, data)
        physics += time.perf_counter() - start
    count = len(states) * TICKS_PER_STATE
    return controller / count * 1e6, physics / count * 1e6


def whole_process(run_dir: Path) -> dict[str, float]:
    """`renderloop fly RUN_DIR --force` as a child process: its simulated and wall seconds, and the seconds of each of
    PARTS (`imports`: from the process's start until its imports are done)."""
    started, start = time.time(), time.perf_counter()
    out = subprocess.run([sys.executable, "-c", TIMED_FLY, str(run_dir)], check=True, capture_output=True, text=True).stdout
    wall = time.perf_counter() - start
    parts = json.loads(out.splitlines()[-1])
    simulated = float(read_csv(run_dir / "flight.csv", FLIGHT_HEADER)[-1, 0])
    return {"simulated": simulated, "wall": wall, "imports": parts.pop("imported") - started, **parts}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per repeat of the closed loop")
    parser.add_argument("--process-repeats", type=int, default=3, help="runs of the whole `renderloop fly`")
    parser.add_argument("--name", default="fly_speed", help="Results file: benchmarks/results/NAME.json.")
    # benchmarks/run.py reads every measurement from here; its short runs must not replace the docs' figures
    parser.add_argument("--json", type=Path, help="write every measurement here instead of the results file")
    args = parser.parse_args()
    if args.process_repeats < 1:
        parser.error("--process-repeats must be at least 1: the results hold the process's figures")
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core, the child processes' too

    config = load_config("paper", seed=7)
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp)
        run_scene(run_dir, config)
        run_plan(run_dir, config)
        table = read_csv(run_dir / "trajectory.csv", TRAJECTORY_HEADER)
        model = mujoco.MjModel.from_xml_path(str(run_dir / "world.xml"))
        count = min(len(table), int(args.seconds * config.planner.sample_rate_hz) + 1)
        reference = Reference(table[:count, 0], table[:count, 1:8], table[:count, 8:15], table[:count, 15:22])
        uav = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "uav")
        hover = 9.81 * float(model.body_subtreemass[uav]) / (4 * config.robot.rotor.kf)  # w² at hover

        physics = [physics_only(model, hover, args.seconds) for _ in range(args.repeats)]
        factor = [closed_loop(model, config, reference) for _ in range(args.repeats)]
        states = flight_states(model, config, reference)
        split = [tick_split(model, config, reference, states) for _ in range(args.repeats)]
        process = [whole_process(run_dir) for _ in range(args.process_repeats)]
    steps_per_control = 1.0 / (config.controller.rate_hz * config.controller.physics_dt)
    results = {
        "physics_steps_per_s": summary(physics),
        "physics_real_time_factor": summary([p * config.controller.physics_dt for p in physics]),
        "closed_loop_real_time_factor": summary(factor),
        "closed_loop_physics_steps_per_s": summary([f / config.controller.physics_dt for f in factor]),
        "controller_us_per_tick": summary([c for c, _ in split]),
        "physics_us_per_tick": summary([p for _, p in split]),
        "reference_real_time_factor": 1.0,
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "simulated_seconds": float(reference.t[-1]),
        "physics_steps_per_control_tick": steps_per_control,
        "controller_states_timed": len(states),
        "process_real_time_factor": summary([run["simulated"] / run["wall"] for run in process]),
        "process_wall_s": summary([run["wall"] for run in process]),
        "process_simulated_seconds": process[0]["simulated"],
        "process_parts_s": {part: summary([run[part] for run in process]) for part in PARTS},
    }
    print(f"fly benchmark, paper preset, one core, {args.repeats} repeats of {reference.t[-1]:.0f} s simulated")
    print(f"{'figure':<44}{'median':>12}{'min':>12}{'max':>12}")
    names = ["physics_steps_per_s", "physics_real_time_factor", "closed_loop_physics_steps_per_s", "closed_loop_real_time_factor",
             "controller_us_per_tick", "physics_us_per_tick"]
    parts = results["process_parts_s"]
    rows = [(name, results[name]) for name in names + ["process_wall_s", "process_real_time_factor"]]
    for name, row in rows + [(f"process: {part}_s", parts[part]) for part in PARTS]:
        print(f"{name:<44}{row['median']:>12.2f}{row['min']:>12.2f}{row['max']:>12.2f}")
    print(f"(process: `renderloop fly` on the whole {results['process_simulated_seconds']:.0f} s scan, {len(process)} runs)")
    print(f"{'reference (Gazebo/RotorS) real-time factor':<44}{1.0:>12.1f}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")
        return
    process_rtf = results["process_real_time_factor"]
    figures = {  # what docs/stages/fly.md reads, rounded as it shows them
        "closed_loop_rtf": round(results["closed_loop_real_time_factor"]["median"]),
        "physics_us_per_tick": round(results["physics_us_per_tick"]["median"]),
        "controller_us_per_tick": round(results["controller_us_per_tick"]["median"]),
        "process_rtf": round(process_rtf["median"]),
        "process_rtf_range": f"{process_rtf['min']:.1f}-{process_rtf['max']:.1f}",
        "process_s": round(results["process_wall_s"]["median"], 1),
        "scan_s": round(results["process_simulated_seconds"]),
        "imports_s": round(parts["imports"]["median"], 1),
        "trajectory_s": round(parts["trajectory"]["median"], 1),
        "flight_s": round(parts["flight"]["median"]),
        "flight_csv_s": round(parts["flight_csv"]["median"], 2),
        "figures_s": f"{parts['figures']['min']:.1f}-{parts['figures']['max']:.1f}",
    }
    print(save_result(args.name, figures))


if __name__ == "__main__":
    main()
