"""`renderloop eval`: one full run per seed, on local processes or Ray tasks, then the table.

Each seed is one run directory `OUT/seed_<n>` made by the same pipeline as `renderloop run`,
so an interrupted evaluation resumes stage by stage and a single seed can be inspected
(or reported) like any run. Runs share the cores: each renderer gets cores / workers
threads. With Ray, OUT must be on a file system every node sees.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from pathlib import Path

from rich.console import Console

from renderloop.config import Config
from renderloop.evaluation.table import Scenario, scenario
from renderloop.io import ownership
from renderloop.parallel import LOCAL, Executor, map_tasks
from renderloop.pipeline import check_inputs, run_pipeline
from renderloop.rundir import files
from renderloop.rundir.stage import claim

Progress = Callable[[int, int], None]


def run_dir_of(out: Path, config: Config) -> Path:
    """seed_<n> for the static scan, seed_<n>_adaptive for the adaptive mission: both side by side in one evaluation."""
    kind = config.mission.kind
    return Path(out) / (f"seed_{config.seed}" if kind == "static" else f"seed_{config.seed}_{kind}")


def run_seed(out: Path, config: Config, force: bool) -> Scenario:
    """One scenario end to end, quietly (many run at once; the caller shows one progress bar)."""
    run_dir = run_dir_of(out, config)
    run_pipeline(run_dir, config, force, Console(file=io.StringIO()))
    return scenario(config.seed, config.mission.kind, run_dir)


def evaluate(base: Config, seeds: list[int], out: Path, executor: Executor = LOCAL, force: bool = False,
             progress: Progress | None = None, missions: tuple[str, ...] | None = None) -> list[Scenario]:
    """Every seed's scenario under each mission (default the config's), in seed order; `progress` hears (runs
    finished, runs) as they finish."""
    check_inputs(base)  # every run shares the detector: refused once, before OUT or any run is made
    out = ownership.claim(Path(out), ownership.EVAL)
    shared = executor.share_cores(base)
    kinds = missions or (base.mission.kind,)
    configs = [shared.override({"seed": seed, "mission": {"kind": kind}}) for seed in seeds for kind in kinds]
    for config in configs:  # refuse before any work, not after hours of it
        claim(run_dir_of(out, config))
        if not force:
            files.check_config(run_dir_of(out, config), config)
    runs = map_tasks(executor, run_seed, [(out, config, force) for config in configs])
    finished: list[Scenario] = []
    if progress:
        progress(0, len(configs))
    for result in runs:
        finished.append(result)
        if progress:
            progress(len(finished), len(configs))
    return sorted(finished, key=lambda s: (seeds.index(s.seed), kinds.index(s.mission)))
