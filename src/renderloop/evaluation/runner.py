"""`renderloop eval`: one full run per seed, on local processes or Ray tasks, then the table.

Each seed is one run directory `OUT/seed_<n>` made by the same pipeline as `renderloop run`,
so an interrupted evaluation resumes stage by stage and a single seed can be inspected
(or reported) like any run. Runs share the cores: each renderer gets cores / workers
threads. With Ray, OUT must be on a file system every node sees.
"""

from __future__ import annotations

import io
import re
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

from rich.console import Console

from renderloop.config import Config
from renderloop.evaluation.table import EVAL_CSV, EVAL_JSON, Scenario, scenario
from renderloop.pipeline import run_pipeline
from renderloop.render.executor import (
    ray_session,
    spawn_safely,
    threads_per_worker,
)
from renderloop.rundir import files, ownership
from renderloop.rundir.stage import claim

Progress = Callable[[int, int], None]


def run_dir_of(out: Path, config: Config) -> Path:
    """seed_<n> for the static scan, seed_<n>_adaptive for the adaptive mission: both side by side in one evaluation."""
    kind = config.mission.kind
    return Path(out) / (f"seed_{config.seed}" if kind == "static" else f"seed_{config.seed}_{kind}")


def _older_evaluation(directory: Path) -> bool:
    """An evaluation from before the ownership mark: only seed runs and the table in it."""
    return all(re.fullmatch(r"seed_\d+(_adaptive)?", entry.name) or entry.name in (EVAL_CSV, EVAL_JSON) for entry in directory.iterdir())


def run_seed(out: Path, config: Config, force: bool) -> Scenario:
    """One scenario end to end, quietly (many run at once; the caller shows one progress bar)."""
    run_dir = run_dir_of(out, config)
    run_pipeline(run_dir, config, force, Console(file=io.StringIO()))
    return scenario(config.seed, config.mission.kind, run_dir)


def _local(out: Path, configs: list[Config], force: bool, workers: int) -> Iterator[Scenario]:
    if workers <= 1:
        for config in configs:
            yield run_seed(out, config, force)
        return
    # spawn, not fork: the runs render with Blender and MuJoCo, neither survives a fork
    with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
        with spawn_safely():
            futures = [pool.submit(run_seed, out, config, force) for config in configs]
        for future in as_completed(futures):
            yield future.result()


def _ray(out: Path, configs: list[Config], force: bool, workers: int, address: str | None) -> Iterator[Scenario]:
    import ray

    with ray_session(workers, address):
        task = ray.remote(num_cpus=1)(run_seed)
        pending = [task.remote(out, config, force) for config in configs]
        while pending:
            [finished], pending = ray.wait(pending, num_returns=1)
            yield ray.get(finished)


def evaluate(base: Config, seeds: list[int], out: Path, workers: int = 1, executor: str = "local",
             address: str | None = None, force: bool = False, progress: Progress | None = None,
             missions: tuple[str, ...] | None = None) -> list[Scenario]:
    """Every seed's scenario under each mission (default the config's), in seed order; `progress` hears (runs
    finished, runs) as they finish."""
    out = ownership.claim(Path(out), ownership.EVAL, adopt=_older_evaluation)
    shared = threads_per_worker(base, workers)
    kinds = missions or (base.mission.kind,)
    configs = [shared.model_copy(update={"seed": seed, "mission": shared.mission.model_copy(update={"kind": kind})})
               for seed in seeds for kind in kinds]
    for config in configs:  # refuse before any work, not after hours of it
        claim(run_dir_of(out, config))
        if not force:
            files.check_config(run_dir_of(out, config), config)
    runs = _ray(out, configs, force, workers, address) if executor == "ray" else _local(out, configs, force, workers)
    finished: list[Scenario] = []
    if progress:
        progress(0, len(configs))
    for result in runs:
        finished.append(result)
        if progress:
            progress(len(finished), len(configs))
    return sorted(finished, key=lambda s: (seeds.index(s.seed), kinds.index(s.mission)))
