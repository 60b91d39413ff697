"""`renderloop run`: every stage in order with one progress display, skipping complete ones.

Stages are listed here in pipeline order; each is a function (run_dir, config, force,
progress) -> bool that returns False when its outputs were already complete, and may
report (done, total) units of work. A killed run therefore resumes where it stopped.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from renderloop.config import Config
from renderloop.counting import stage as count_stage
from renderloop.io.atomic import write_json
from renderloop.perception import stage as detect_stage
from renderloop.planning import stage as plan_stage
from renderloop.render import stage as render_stage
from renderloop.scene import stage as scene_stage
from renderloop.sim import stage as fly_stage

ReportFn = Callable[[int, int], None]
TIMINGS = "timings.json"


@dataclass(frozen=True)
class Stage:
    name: str
    outputs: tuple[str, ...]
    run: Callable[[Path, Config, bool, ReportFn], bool]


STAGES = (
    Stage("scene", scene_stage.OUTPUTS, lambda run_dir, config, force, _: scene_stage.run_scene(run_dir, config, force)),
    Stage("plan", plan_stage.OUTPUTS, lambda run_dir, config, force, _: plan_stage.run_plan(run_dir, config, force)),
    Stage("fly", fly_stage.OUTPUTS, lambda run_dir, config, force, _: fly_stage.run_fly(run_dir, config, force)),
    Stage("render", render_stage.OUTPUTS,
          lambda run_dir, config, force, progress: render_stage.run_render(run_dir, config, force, progress=progress)),
    Stage("detect", detect_stage.OUTPUTS,
          lambda run_dir, config, force, progress: detect_stage.run_detect(run_dir, config, force, progress=progress)),
    Stage("count", count_stage.OUTPUTS, lambda run_dir, config, force, _: count_stage.run_count(run_dir, config, force)),
)


def run_pipeline(run_dir: Path, config: Config, force: bool = False, console: Console | None = None) -> dict[str, float]:
    """Run every stage; returns the seconds each one took (0 when it was skipped)."""
    console = console or Console(stderr=True)
    seconds: dict[str, float] = {}
    columns = (TextColumn("{task.description:<28}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
               TimeElapsedColumn(), TimeRemainingColumn())
    with Progress(*columns, console=console, transient=False) as progress:
        for stage in STAGES:
            task = progress.add_task(stage.name, total=1)
            start = time.perf_counter()
            report = lambda done, total, task=task: progress.update(task, completed=done, total=total)  # noqa: E731
            ran = stage.run(run_dir, config, force, report)
            seconds[stage.name] = time.perf_counter() - start if ran else 0.0
            note = "done" if ran else "complete, skipped"
            total = progress.tasks[task].total or 1
            progress.update(task, completed=total, total=total, description=f"{stage.name} ({note})")
            _record_time(run_dir, stage.name, seconds[stage.name])
    return seconds


def _record_time(run_dir: Path, stage: str, seconds: float) -> None:
    """timings.json keeps the seconds of the last run of each stage; a skipped stage keeps its earlier time."""
    path = Path(run_dir) / TIMINGS
    try:
        timings = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        timings = {}
    if seconds > 0 or stage not in timings:
        updated = {**timings, stage: round(seconds, 2)}
        if updated != timings and Path(run_dir).is_dir():
            write_json(path, updated)
