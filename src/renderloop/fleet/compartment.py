"""`renderloop run` of a scan split by rows (`mission.split: rows`): one mission a row, each a task on the executor.

The compartment's run directory holds the scene once and a run of its own for each row's mission:

    OUT/config.yaml, scene.json, world.xml, scene_topview.png   the compartment (the scene stage, once)
    OUT/rows/row_<id>/    the mission of row <id>: a complete run (`planner.row: <id>`, `mission.split: none`), its
                          scene files copied from OUT, then plan, fly, render, detect and count as `renderloop run`
                          makes them, and its report
    OUT/fleet.json        which UAV flies which row's mission when (`renderloop.fleet.schedule`)
    OUT/counts.json, OUT/harvest.json   the rows' counts merged, and one harvest plan for the compartment

Each row's run is a task of `renderloop.parallel.map_tasks`: in this process, in local processes or on a Ray cluster,
the same files either way (each mission's randomness comes from the run's seed, never from where or when it runs).
With Ray, OUT must be on a file system every node sees, as for `renderloop eval`. A row's run resumes stage by stage
like any run, so a killed compartment resumes where each row stopped.
"""

from __future__ import annotations

import io
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
from rich.console import Console

from renderloop.config import Config
from renderloop.counting.harvest import plan_harvest
from renderloop.counting.merge import merge_counts
from renderloop.counting.summary import scanned_rows
from renderloop.fleet.schedule import Mission, corridor, schedule
from renderloop.io.atomic import atomic_path
from renderloop.parallel import LOCAL, Executor, map_tasks
from renderloop.pipeline import check_inputs, run_pipeline, stages_of
from renderloop.planning.waypoints import footprint_radius, read_waypoints
from renderloop.report.html import write_report
from renderloop.rundir import files, names
from renderloop.rundir.models import Harvest
from renderloop.rundir.stage import claim
from renderloop.scene import stage as scene_stage
from renderloop.scene.model import read_scene

SCENE_FILES = (names.SCENE, names.WORLD, names.TOP_VIEW)  # what a row's run shares with the compartment

Progress = Callable[[int, int], None]


# what only fleet.json follows: a compartment scanned before is scheduled again for other UAVs, its rows kept
SCHEDULE_ONLY = {"mission": {"uavs": 1}}


def row_dir_of(out: Path, row: int) -> Path:
    return Path(out) / names.row_run(row)


def row_config(config: Config, row: int) -> Config:
    """The config of one row's mission: the compartment's, scanning that row only, as one UAV's single mission."""
    return config.override({"planner": {"row": row}, "mission": {"split": "none", "uavs": 1}})


def _share_scene(out: Path, row_dir: Path, config: Config, force: bool) -> None:
    """A row's run starts from the compartment's scene: its config, and the scene files copied where they are missing
    or older than the compartment's (the stages after redo what they made from an older scene, as make does)."""
    claim(row_dir)
    if force or not (row_dir / names.CONFIG).is_file():
        files.write_config(row_dir, config)
    for name in SCENE_FILES:
        source, target = Path(out) / name, row_dir / name
        if not target.is_file() or target.stat().st_mtime_ns < source.stat().st_mtime_ns:
            with atomic_path(target) as tmp:
                shutil.copyfile(source, tmp)


def run_row(out: Path, config: Config, row: int, force: bool) -> int:
    """One row's mission end to end, quietly (several run at once; the caller shows one progress bar)."""
    row_dir = row_dir_of(out, row)
    mission = row_config(config, row)
    _share_scene(out, row_dir, mission, force)
    stages = tuple(stage for stage in stages_of(mission) if stage is not scene_stage.STAGE)
    run_pipeline(row_dir, mission, force, Console(file=io.StringIO()), stages=stages)
    write_report(row_dir, only_if_stale=True)
    return row


def mission_of(out: Path, config: Config, row: int) -> Mission:
    """A row's flown mission as the fleet's schedule sees it: how long it flew, and the corridor its scan occupies
    (its scan waypoints, grown by the UAV's footprint)."""
    row_dir = row_dir_of(out, row)
    scan = np.array([w.dofs[:2] for w in read_waypoints(row_dir) if w.kind == "scan"], dtype=float).reshape(-1, 2)
    return Mission(row, float(files.read_flight(row_dir)["t"][-1]), corridor(scan, footprint_radius(config)))


def run_compartment(out: Path, config: Config, force: bool = False, executor: Executor = LOCAL,
                    progress: Progress | None = None) -> dict[int, float]:
    """The compartment's scene, every scanned row's run (tasks on `executor`), then fleet.json, counts.json and
    harvest.json; returns the rows' missions' flight seconds by row. `progress` hears (rows finished, rows)."""
    out = Path(out)
    claim(out, write=False)
    if not force:
        files.check_config(out, config, remade=SCHEDULE_ONLY)
        if (out / names.CONFIG).is_file():  # the UAVs asked for now: fleet.json, written below, follows them
            files.write_config(out, config)
    check_inputs(config)  # every row shares the detector: refused once, before any row's run
    executor.check_answers()  # and the cluster they run on, before the compartment's scene is built
    scene_stage.STAGE.run(out, config, force)
    rows = scanned_rows(config) or [row.id for row in read_scene(out).rows]  # planner.row, or every row
    shared = executor.share_cores(config)
    for row in rows:  # a row directory that is not ours, or made with another config, is refused before any work
        claim(row_dir_of(out, row), write=False)
        if not force:
            files.check_config(row_dir_of(out, row), row_config(shared, row))
    if progress:
        progress(0, len(rows))
    for done, _ in enumerate(map_tasks(executor, run_row, [(out, shared, row, force) for row in rows]), 1):
        if progress:
            progress(done, len(rows))
    missions = [mission_of(out, config, row) for row in rows]
    files.write_model(out / names.FLEET, schedule(missions, config.mission.uavs))
    counts = merge_counts([files.read_counts(row_dir_of(out, row)) for row in rows])
    estimates = {plant.id: plant.estimate for plant in counts.plants}
    harvest = Harvest.model_validate(plan_harvest(read_scene(out), estimates, config.counting.harvest_min_ripe), strict=False)
    files.write_model(out / names.HARVEST, harvest)
    files.write_model(out / names.COUNTS, counts)
    return {mission.row: mission.duration_s for mission in missions}
