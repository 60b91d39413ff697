"""A scan of one row (`planner.row`) is counted and scored against that row alone, and every row's ripe-count
distribution is in counts.json.

The paper scene (8 rows of 4 plants) with synthetic detections of every row's fruit, as a one-row scan sees the
neighbouring rows' fruit past its own; no rendering (tests/test_counting.py's run directories).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from test_counting import FRAMES, detections_document, false_positives, make_run

from renderloop.config import CountingConfig
from renderloop.counting.stage import run_count
from renderloop.counting.summary import count_scan
from renderloop.counting.uncertainty import central_interval
from renderloop.errors import UserError
from renderloop.rundir import files, names
from renderloop.rundir.models import Counts, Detections, Harvest
from renderloop.scene.model import Scene


def every_rows_fruit(scene: Scene, seed: int = 3) -> dict[str, np.ndarray]:
    """3-20 noisy views of every fruit of every row, and blobs of false positives off the first row's plants."""
    rng = np.random.default_rng(seed)

    def views(ripe: bool) -> np.ndarray:
        clouds = [np.array(p.center) + rng.normal(0.0, 0.0065, size=(int(rng.integers(3, 21)), 3))
                  for p in scene.peppers if p.ripe == ripe]
        return np.vstack(clouds) if clouds else np.zeros((0, 3))

    return {"ripe": np.vstack([views(True), false_positives(scene, rng)]), "unripe": views(False)}


def scan_poses(seed: int = 4) -> np.ndarray:
    """Camera poses spread over the room, so that fruit are seen from several sides and the intervals vary."""
    poses = np.repeat(np.eye(4)[None], FRAMES, axis=0)
    poses[:, :3, 3] = np.random.default_rng(seed).uniform([-3.0, -4.0, 0.5], [3.0, 4.0, 1.5], size=(FRAMES, 3))
    return poses


@pytest.fixture(scope="module")
def detections(paper) -> Detections:
    _, scene = paper
    return Detections.model_validate_json(json.dumps(detections_document(every_rows_fruit(scene))))


def test_a_scene_cut_to_some_rows_keeps_their_plants_and_fruit_and_finds_plants_by_id(paper):
    _, scene = paper
    cut = scene.of_rows([2, 1])
    assert [row.id for row in cut.rows] == [1, 2]
    assert {plant.id for plant in cut.plants} == {i for row in scene.rows[1:3] for i in row.plants}
    assert {p.id for p in cut.peppers} == {p.id for p in scene.peppers if scene.plant(p.plant).row in (1, 2)}
    for plant in cut.plants:
        assert cut.plant(plant.id) is plant
        assert cut.peppers_of(plant.id) == scene.peppers_of(plant.id)
    assert cut.peppers_of(scene.rows[0].plants[0]) == []
    assert scene.of_rows(row.id for row in scene.rows) is scene
    with pytest.raises(UserError, match="no row 9") as error:
        scene.of_rows([1, 9])
    assert "\n" not in str(error.value)


@pytest.mark.parametrize("use_layout", [True, False], ids=["layout", "no layout"])
def test_a_one_row_count_is_what_counting_every_row_gives_that_row(paper, detections, use_layout):
    """The neighbouring rows' fruit, in their plants' boxes or nearer their tables, are neither counted nor removed."""
    config, scene = paper
    counting = CountingConfig(use_layout=use_layout)
    poses = scan_poses()
    whole = count_scan(scene, detections, poses, counting, config.seed, None).counts
    for row_id in (0, 2):
        one = count_scan(scene, detections, poses, counting, config.seed, None, rows=[row_id]).counts
        assert one.rows == [row for row in whole.rows if row.id == row_id]
        assert one.plants == [plant for plant in whole.plants if plant.row == row_id]
        assert one.total.truth == one.rows[0].truth == sum(p.ripe for p in scene.peppers if scene.plant(p.plant).row == row_id)
        assert one.total.interval == one.rows[0].interval  # one row: its distribution is the total's
    assert whole.rows[0].removed > 0  # the false positives by the first row were there to be kept apart


def test_detections_in_another_rows_plants_count_for_nothing_in_the_scanned_row(paper):
    config, scene = paper
    others = {plant.id for plant in scene.plants if plant.row != 1}
    rng = np.random.default_rng(8)
    fruit = np.vstack([np.array(p.center) + rng.normal(0.0, 0.005, size=(10, 3))
                       for p in scene.peppers if p.plant in others and p.ripe])
    detections = Detections.model_validate_json(json.dumps(detections_document({"ripe": fruit, "unripe": np.zeros((0, 3))})))
    counted = count_scan(scene, detections, scan_poses(), config.counting, config.seed, None, rows=[1])
    [row] = counted.counts.rows
    assert (row.id, row.estimate, row.detections, row.removed) == (1, 0, 0, 0)
    assert row.truth > 0 and counted.counts.total.estimate == 0
    assert counted.counts.detections.ripe == 0 and counted.counts.detections.no_position == 1
    assert counted.counts.detections.frames == FRAMES


def test_renderloop_count_of_a_one_row_run_scores_plans_and_plots_that_row_alone(paper, tmp_path: Path):
    config, scene = paper
    config = config.override({"planner": {"row": 1}})
    run = make_run(tmp_path / "run", config, scene, every_rows_fruit(scene))
    assert run_count(run, config)
    counts, harvest = files.read_counts(run), files.read_model(run / names.HARVEST, Harvest)
    mine = [plant.id for plant in scene.plants if plant.row == 1]
    assert [row.id for row in counts.rows] == [1] and [plant.id for plant in counts.plants] == mine
    truth = sum(p.ripe for p in scene.peppers if p.plant in mine)
    assert counts.total.truth == counts.rows[0].truth == truth > 0
    assert abs(counts.total.error_pct) < 25  # every other row's fruit counted as missed would be about -75 %
    assert harvest.stops and {stop.id for stop in harvest.stops} <= set(mine)
    assert harvest.total_expected_ripe == sum(p.estimate for p in counts.plants if p.estimate >= harvest.min_ripe)
    assert sorted(path.name for path in (run / "counts").iterdir()) == ["row_1.png"]
    assert not run_count(run, config)  # current: the scanned row's plot is all it needs

    assert run_count(run, config.override({"planner": {"row": 2}}))  # a count of another row is not current
    assert [row.id for row in files.read_counts(run).rows] == [2]


def test_a_one_row_count_of_a_row_the_scene_lacks_is_one_line(paper, tmp_path: Path):
    config, scene = paper
    config = config.override({"planner": {"row": 5}})
    scene = scene.of_rows([0, 1, 2, 3])  # a scene.json that is not the config's greenhouse
    run = make_run(tmp_path / "run", config, scene, every_rows_fruit(scene))
    with pytest.raises(UserError, match="no row 5") as error:
        run_count(run, config)
    assert "\n" not in str(error.value) and not (run / names.COUNTS).exists()


def test_every_rows_distribution_is_in_counts_json_and_gives_its_interval(paper, tmp_path: Path):
    config, scene = paper
    run = make_run(tmp_path / "run", config, scene, every_rows_fruit(scene))
    run_count(run, config)
    counts = files.read_counts(run)
    assert [row.id for row in counts.rows] == [row.id for row in scene.rows]
    for row in counts.rows:
        pmf = np.array(row.distribution)
        assert pmf.sum() == pytest.approx(1.0, abs=1e-9) and pmf[-1] > 0
        assert central_interval(pmf, row.interval.level) == (row.interval.low, row.interval.high)
        assert pmf[row.estimate] > 0.1  # the count is a likely value of the true count
    assert any(row.interval.high > row.interval.low for row in counts.rows)  # some rows are unsure: a real test


def test_a_counts_json_without_row_distributions_still_reads_and_is_counted_again(paper, tmp_path: Path):
    config, scene = paper
    run = make_run(tmp_path / "run", config, scene, every_rows_fruit(scene))
    run_count(run, config)
    document = json.loads((run / names.COUNTS).read_text())
    for row in document["rows"]:
        del row["distribution"]
    (run / names.COUNTS).write_text(json.dumps(document))
    old = files.read_counts(run)
    assert isinstance(old, Counts) and all(row.distribution is None for row in old.rows)
    assert run_count(run, config)  # a merge needs the distributions: the count is redone to record them
    assert all(row.distribution is not None for row in files.read_counts(run).rows)
