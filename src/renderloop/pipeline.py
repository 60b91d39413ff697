"""`renderloop run`: every stage in order with one progress display, skipping complete ones.

Stages are listed here in pipeline order; each is a `renderloop.rundir.stage.Stage`, whose
`run` returns False when its outputs were already complete and may report (done, total)
units of work. A killed run therefore resumes where it stopped.
"""

from __future__ import annotations

import time
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
from renderloop.loop import stage as online_stage
from renderloop.parallel import LOCAL, Executor
from renderloop.perception import stage as detect_stage
from renderloop.perception.detector import Detector
from renderloop.planning import stage as plan_stage
from renderloop.render import stage as render_stage
from renderloop.rundir.files import check_config, record_timing
from renderloop.rundir.stage import Stage, claim
from renderloop.scene import stage as scene_stage
from renderloop.sim import stage as fly_stage

STAGES: tuple[Stage, ...] = (scene_stage.STAGE, plan_stage.STAGE, fly_stage.STAGE, render_stage.STAGE, detect_stage.STAGE,
                             count_stage.STAGE)
# `mission.online`: fly, render and detect as one loop (renderloop.loop.stage), the same files in the end
ONLINE_STAGES: tuple[Stage, ...] = (scene_stage.STAGE, plan_stage.STAGE, online_stage.STAGE, count_stage.STAGE)


# `mission.kind: adaptive`: the loop online, steered by what it counts (renderloop.loop.mission)
ADAPTIVE_STAGES: tuple[Stage, ...] = (scene_stage.STAGE, plan_stage.STAGE, online_stage.ADAPTIVE_STAGE, count_stage.STAGE)


def stages_of(config: Config) -> tuple[Stage, ...]:
    if config.mission.kind == "adaptive":
        return ADAPTIVE_STAGES
    return ONLINE_STAGES if config.mission.online else STAGES


def check_inputs(config: Config) -> None:
    """Refuse, in one line, what the config names that a later stage would refuse only after the ones before it had
    run (minutes to an hour): the detector model, loaded and probed as the detect stage loads it."""
    Detector(config.detector.model)


def run_pipeline(run_dir: Path, config: Config, force: bool = False, console: Console | None = None,
                 executor: Executor = LOCAL, stages: tuple[Stage, ...] | None = None) -> dict[str, float]:
    """Run every stage (or `stages`, in their order); returns the seconds each one took (0 when it was skipped). The
    stages that spread work (the batch render) spread it on `executor`."""
    claim(run_dir, write=False)  # a directory that is not ours is refused before the progress display starts
    if not force:
        check_config(run_dir, config)  # so is one made with another config, naming the fields that differ
    check_inputs(config)  # before the first stage writes anything
    console = console or Console(stderr=True)
    seconds: dict[str, float] = {}
    columns = (TextColumn("{task.description:<28}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
               TimeElapsedColumn(), TimeRemainingColumn())
    with Progress(*columns, console=console, transient=False) as progress:
        for stage in stages or stages_of(config):
            task = progress.add_task(stage.name, total=1)
            start = time.perf_counter()
            report = lambda done, total, task=task: progress.update(task, completed=done, total=total)  # noqa: E731
            ran = stage.run(run_dir, config, force, report, executor)
            seconds[stage.name] = time.perf_counter() - start if ran else 0.0
            note = "done" if ran else "complete, skipped"
            total = progress.tasks[task].total or 1
            progress.update(task, completed=total, total=total, description=f"{stage.name} ({note})")
            record_timing(run_dir, stage.name, seconds[stage.name])
    return seconds
