"""Real-time factor of the closed loop online: the robot flies, the camera renders at its rate, perception runs on every frame.

Paper preset, the scan's first `--seconds` simulated seconds, in one run side by side:
- flight alone (the Simulation stepped, no sensor),
- flight + raster camera at 5 Hz (MuJoCo, in this process) + online detection (on a thread of its own, as the
  loop stage runs it) and counting, with the detector's default passes (windows and mirror) and with the whole
  frame searched once; the frames as images, as a mission reads them, and (last row) with their PNGs compressed
  as `renderloop run --online` writes them,
- flight + Cycles camera at `--cycles-rate` in `--workers` processes + online detection (with --cycles),
  and how long the physics waited for frames: it waits only when perception asks for a frame that is
  not rendered yet, never while a frame renders that nobody needs yet.
Goal (issue 23): at least 5x real time with the raster camera at 5 Hz and detection, on 2 cores.

    .venv/bin/python benchmarks/loop.py [--seconds 20] [--repeats 3] [--cycles] [--workers 2] [--name loop]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from common import save_result

from renderloop.config import Config, load_config
from renderloop.counting.online import OnlineCounter
from renderloop.loop.simulation import Simulation
from renderloop.loop.perceive import OnlinePerception


def _config(backend: str, rate_hz: float, one_pass: bool = False, fast_look: bool = False) -> Config:
    data = load_config("paper", seed=7).model_dump(mode="json")
    data["renderer"]["backend"] = backend
    data["camera"]["rate_hz"] = rate_hz
    if one_pass:
        data["detector"].update(windows=[], mirror=False)
    if fast_look:
        data["renderer"]["raster"].update(antialias=0)
    return Config.model_validate(data)


def closed_loop(run_dir: Path, config: Config, seconds: float, camera: bool, workers: int = 1,
                encode: bool = False) -> tuple[float, float, int]:
    """Simulated seconds per wall second, seconds spent waiting for frames, frames taken. Perception on its own
    thread, as the loop stage runs it; `encode`: the frames' PNGs compressed as they render, as
    `renderloop run --online` does to write them (the files are not written)."""
    with Simulation(config, run_dir) as sim, \
            OnlinePerception(config, OnlineCounter(sim.scene, config.counting, config.seed), thread=True) as perception:
        sim.follow(sim.scan_trajectory())
        cam = sim.add_camera(workers=workers, encode=encode) if camera else None
        taken, waited = 0, 0.0

        def take(wait: bool) -> None:
            nonlocal taken
            while cam is not None and taken < len(cam) and (wait or cam.ready(taken)):
                frame = cam.frame(taken)
                if encode:
                    frame.files  # noqa: B018 -- what the loop stage writes: the PNGs compressed on the camera's thread
                perception.submit(frame)
                cam.release(taken)
                taken += 1
            perception.collect(wait)

        start = time.perf_counter()
        while sim.t < seconds and not sim.finished:
            sim.step()
            if not sim.tick % 10:  # as the loop stage looks
                take(wait=False)
        before = time.perf_counter()
        take(wait=True)  # the end of the run: the last frames are waited for
        waited = time.perf_counter() - before
        perception.counter.counts()
        return sim.t / (time.perf_counter() - start), waited, taken


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="simulated seconds of the scan per repeat")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cycles", action="store_true", help="also the Cycles camera (slow: about 1 s a frame a core)")
    parser.add_argument("--cycles-rate", type=float, default=1.0, help="Cycles camera rate, Hz")
    parser.add_argument("--workers", type=int, default=2, help="Cycles render processes")
    parser.add_argument("--name", default="loop", help="Results file: benchmarks/results/NAME.json.")
    args = parser.parse_args()

    rows: list[tuple[str, list[float]]] = []
    cycles_figures = None
    with tempfile.TemporaryDirectory() as tmp:
        def rates(name: str, config: Config, **options) -> list[float]:
            run_dir = Path(tmp) / name
            closed_loop(run_dir, config, 1.0, camera=True)  # scene, plan, detector and GL context made once, untimed
            return [closed_loop(run_dir, config, args.seconds, camera=True, **options)[0] for _ in range(args.repeats)]

        raster = _config("raster", 5.0)
        default = rates("default", raster)
        rows.append(("flight alone", [closed_loop(Path(tmp) / "default", raster, args.seconds, camera=False)[0]
                                      for _ in range(args.repeats)]))
        rows.append(("raster camera 5 Hz + detection, the defaults (4x multisampling; the detector's windows and mirror)",
                     default))
        rows.append(("the same, the detector's one pass over the whole frame",
                     rates("one_pass", _config("raster", 5.0, one_pass=True))))
        fast = _config("raster", 5.0, one_pass=True, fast_look=True)
        rows.append(("the same, the raster view without multisampling", rates("fast", fast)))
        rows.append(("the same, the frames' PNGs compressed as `renderloop run --online` writes them",
                     rates("fast_png", fast, encode=True)))
        if args.cycles:
            rate, waited, frames = closed_loop(Path(tmp) / "cycles", _config("cycles", args.cycles_rate), args.seconds,
                                               camera=True, workers=args.workers)
            rows.append((f"Cycles camera {args.cycles_rate:g} Hz, {args.workers} worker processes + detection", [rate]))
            wall = args.seconds / rate
            cycles_figures = {"wall_s": round(wall, 1), "waiting_for_last_frames_s": round(waited, 1),
                              "flight_and_requests_s": round(wall - waited, 1), "frames": frames}
    table = [[name, float(f"{statistics.median(values):.3g}"),
              f"{min(values):.3g}-{max(values):.3g}" if len(values) > 1 else "one run"] for name, values in rows]
    print(f"closed loop online, paper preset seed 7, {args.seconds:g} s simulated, {args.repeats} repeats")
    for name, median, spread in table:
        print(f"{name:<110}{median:>8}{spread:>14}")
    figures = {"table": {"columns": [f"loop, paper preset seed 7, {args.seconds:g} s simulated",
                                     "real-time factor, median", "min-max"], "rows": table}}
    if cycles_figures is not None:
        figures["cycles"] = cycles_figures
    print(save_result(args.name, figures))


if __name__ == "__main__":
    main()
