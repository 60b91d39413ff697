"""What the raster quick look is good for: the demo run end to end with `--backend raster` beside Cycles.

The demo preset, one seed, every stage of `renderloop run` (scene, plan, fly, render, detect, count) once per
backend in its own run directory, side by side in one process. Per backend: the shipped detector's ripe recall and
its false-detection share against the masks (detection_scores.json), the ripe and green fruit counted against the
truth (counts.json), and the render stage's seconds per frame (timings.json over render.json's frames: the
renderer's build included, one worker, as `renderloop run` renders by default). Both runs fly the same
trajectory and take the same poses: only the frames differ.

    .venv/bin/python benchmarks/raster_vs_cycles.py [--seed 0] [--out DIR] [--json out.json]

Saves `benchmarks/results/raster_vs_cycles.json` (`save_result`), its table under `table`.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from common import save_result
from rich.console import Console

from renderloop.config import load_config
from renderloop.pipeline import run_pipeline
from renderloop.rundir import names

BACKENDS = ("raster", "cycles")
COLUMNS = ["backend", "ripe recall", "false detections", "ripe counted", "ripe true", "green counted", "green true",
           "ripe error %", "frames", "render s per frame", "run wall s"]


def one_run(run_dir: Path, backend: str, seed: int) -> dict:
    """The demo pipeline with `backend` into `run_dir`; the figures its files hold."""
    config = load_config("demo", seed=seed).override({"renderer": {"backend": backend}})
    start = time.perf_counter()
    seconds = run_pipeline(run_dir, config, console=Console(stderr=True))
    wall = time.perf_counter() - start
    scores = json.loads((run_dir / names.DETECTION_SCORES).read_text())
    total = json.loads((run_dir / names.COUNTS).read_text())["total"]
    frames = json.loads((run_dir / names.RENDER_RECORD).read_text())["frames"]
    return {
        "backend": backend,
        "ripe_recall": scores["ripe_recall"],
        "false_rate": scores["false_rate"],
        "ripe_found": scores["ripe_found"],
        "ripe_findable": scores["ripe_findable"],
        "false_detections": scores["false_detections"],
        "detections_scored": scores["detections_scored"],
        "ripe_counted": total["estimate"],
        "ripe_true": total["truth"],
        "green_counted": total["unripe_estimate"],
        "green_true": total["unripe_truth"],
        "ripe_error_pct": total["error_pct"],
        "exact_plants": total["exact_plants"],
        "frames": frames,
        "render_s_per_frame": seconds["render"] / frames if frames else None,
        "stage_seconds": seconds,
        "run_wall_s": wall,
    }


def row(figures: dict) -> list:
    def rounded(value, digits=3):
        return None if value is None else round(value, digits)

    return [figures["backend"], rounded(figures["ripe_recall"]), rounded(figures["false_rate"]), figures["ripe_counted"],
            figures["ripe_true"], figures["green_counted"], figures["green_true"], rounded(figures["ripe_error_pct"], 1),
            figures["frames"], rounded(figures["render_s_per_frame"], 4), rounded(figures["run_wall_s"], 1)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None, help="keep the two run directories here (default: a temporary one)")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures here")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        root = args.out or Path(scratch)
        runs = [one_run(root / backend, backend, args.seed) for backend in BACKENDS]
    figures = {"seed": args.seed, "preset": "demo", "runs": {run["backend"]: run for run in runs},
               "table": {"columns": COLUMNS, "rows": [row(run) for run in runs]}}
    path = save_result("raster_vs_cycles", figures)
    if args.json is not None:
        args.json.write_text(json.dumps(figures, indent=1, sort_keys=True) + "\n")
    print(" | ".join(COLUMNS))
    for values in figures["table"]["rows"]:
        print(" | ".join("-" if v is None else str(v) for v in values))
    print(f"saved {path}")


if __name__ == "__main__":
    main()
