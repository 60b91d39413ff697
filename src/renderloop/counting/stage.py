"""`renderloop count DIR`: count the fruit per plant and per row from detections.json; plan the harvest.

Reads `config.yaml`, `scene.json` (layout and truth), `groundtruth.txt` (how many
frames were flown, and where the camera was for each: the sides each fruit was seen
from, for the count's intervals) and `detections.json`; counts the rows the scan visited
(`planner.row`, every row when null) and writes one clustering plot per such row in
`counts/row_<id>.png`, then `harvest.json` (`renderloop.counting.harvest`) and
`counts.json` last (`renderloop.rundir.models.Counts`): the settings it records
(counting config and seed) and the rows it holds mark the stage done, so changing them,
or --no-layout, redoes it even when no input changed.
"""

from __future__ import annotations

from pathlib import Path

from renderloop.config import Config
from renderloop.counting.cluster import CLASSES
from renderloop.counting.plots import draw_row
from renderloop.counting.summary import count_scan, run_counting, scanned_rows, settings_of, truth_counts
from renderloop.counting.visibility import fruit_visibility
from renderloop.errors import UserError
from renderloop.rundir import files, names
from renderloop.rundir.stage import Job, Stage
from renderloop.scene.model import read_scene

NEEDS = (names.CONFIG, names.SCENE, names.POSES, names.DETECTIONS)


def _current(run_dir: Path, config: Config) -> bool:
    """counts.json was made with these counting settings, of the rows scanned, with each row's distribution, and every
    scanned row's plot is there."""
    try:
        recorded = files.read_counts(run_dir)
        rows = scanned_rows(config)
        scene = read_scene(run_dir) if rows is None else read_scene(run_dir).of_rows(rows)
    except UserError:
        return False
    plots = all((run_dir / names.row_plot(row.id)).is_file() for row in scene.rows)
    of_scan = [row.id for row in recorded.rows] == [row.id for row in scene.rows]
    merged = all(row.distribution is not None for row in recorded.rows)  # what a merge of rows' counts adds up
    return plots and of_scan and merged and recorded.settings == settings_of(run_counting(config), config.seed)


def _count(run_dir: Path, config: Config, job: Job) -> None:
    scene = read_scene(run_dir)
    times, poses = files.read_poses(run_dir)
    detections = files.read_detections(run_dir, len(times))
    counted = count_scan(scene, detections, poses, run_counting(config), config.seed, fruit_visibility(run_dir, len(times)),
                         scanned_rows(config))
    truth = truth_counts(counted.scene)
    for index, row in enumerate(counted.scene.rows):
        path = run_dir / names.row_plot(row.id)
        path.parent.mkdir(exist_ok=True)
        draw_row(counted.scene, [counted.rows[label][index] for label in CLASSES], truth, path)
    files.write_model(run_dir / names.HARVEST, counted.harvest)
    files.write_model(run_dir / names.COUNTS, counted.counts)  # last: its settings record marks the stage done


STAGE = Stage("count", needs=NEEDS, work=_count, current=_current)
run_count = STAGE.run
