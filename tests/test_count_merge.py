"""The compartment's count from its rows' missions: `merge_counts` of one-row counts is the count of those rows together.

The paper scene (8 rows of 4 plants) with synthetic detections of every row's fruit (tests/test_count_scope.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from test_count_scope import every_rows_fruit, scan_poses
from test_counting import detections_document, make_run

from renderloop.counting.merge import merge_counts
from renderloop.counting.stage import run_count
from renderloop.counting.summary import count_scan
from renderloop.counting.uncertainty import central_interval
from renderloop.counting.visibility import Seen
from renderloop.errors import UserError
from renderloop.rundir import files
from renderloop.rundir.models import Counts, Detections


def as_read(counts: Counts) -> Counts:
    """The counts as the fleet reads them back from a row's counts.json."""
    return Counts.model_validate_json(counts.model_dump_json())


@pytest.fixture(scope="module")
def scan(paper):
    """What one scan of the paper scene found, and how it saw each fruit: some never, some too small, the rest well."""
    config, scene = paper
    detections = Detections.model_validate_json(json.dumps(detections_document(every_rows_fruit(scene))))
    seen = {p.id: Seen(3, (40, 40)) if p.id % 5 else Seen(1, (4, 4)) for p in scene.peppers if p.id % 7}
    return config, scene, detections, seen


def counted(scan, rows: list[int] | None) -> Counts:
    config, scene, detections, seen = scan
    return count_scan(scene, detections, scan_poses(), config.counting, config.seed, seen, rows=rows).counts


def test_a_merge_of_one_count_is_that_count(scan):
    for rows in ([3], None):
        part = as_read(counted(scan, rows))
        assert merge_counts([part]) == part


def test_a_merge_of_two_rows_counts_is_the_count_of_the_two_rows_together(scan):
    together = counted(scan, [2, 5])
    parts = [as_read(counted(scan, [5])), as_read(counted(scan, [2]))]
    merged = merge_counts(parts)
    assert merged.plants == together.plants and merged.rows == together.rows  # sorted by id, whichever part came first
    assert merged.total == together.total  # estimates, truth, error, exact plants, the scan's misses, the interval
    assert merged.total.unseen > 0 and merged.total.too_small > 0  # the misses were there to add up
    assert merged.settings == together.settings
    tally, one = merged.detections, together.detections
    assert (tally.ripe, tally.unripe, tally.removed, tally.unripe_removed) == (one.ripe, one.unripe, one.removed,
                                                                              one.unripe_removed)
    assert (tally.frames, tally.no_position) == (2 * one.frames, 2 * one.no_position)  # two missions' frames
    pmf = np.convolve(*[np.array(row.distribution) for row in merged.rows])
    assert (merged.total.interval.low, merged.total.interval.high) == central_interval(pmf, merged.total.interval.level)
    assert merged.total.interval.high > merged.total.interval.low  # an unsure total: the convolution is tested


def test_the_row_missions_of_a_compartment_merge_into_its_whole_count(paper, tmp_path: Path):
    """As the fleet does it: one run directory a row, each counted by `renderloop count` and read back."""
    config, scene = paper
    points = every_rows_fruit(scene)
    whole = make_run(tmp_path / "whole", config, scene, points)
    run_count(whole, config)
    parts = []
    for row in scene.rows:
        one = config.override({"planner": {"row": row.id}})
        run = make_run(tmp_path / f"row_{row.id}", one, scene, points)
        run_count(run, one)
        parts.append(files.read_counts(run))
    merged, expected = merge_counts(parts), files.read_counts(whole)
    assert (merged.plants, merged.rows, merged.total) == (expected.plants, expected.rows, expected.total)
    assert merged.detections.ripe == expected.detections.ripe


def test_a_row_counted_in_two_parts_is_refused_naming_it(scan):
    with pytest.raises(UserError, match="row 4 is counted in part 0 and in part 1") as error:
        merge_counts([as_read(counted(scan, [4])), as_read(counted(scan, [1, 4]))])
    assert "\n" not in str(error.value)


def test_parts_counted_with_other_settings_are_refused_naming_the_setting(scan):
    part = as_read(counted(scan, [1]))
    other = part.model_copy(update={"rows": [part.rows[0].model_copy(update={"id": 2})], "plants": [],
                                    "settings": {**part.settings, "seed": part.settings["seed"] + 1}})
    with pytest.raises(UserError, match="seed") as error:
        merge_counts([part, other])
    assert "\n" not in str(error.value)
    with pytest.raises(UserError, match="no counts"):
        merge_counts([])


def test_a_row_without_its_distribution_leaves_the_merged_total_without_an_interval(scan):
    old = as_read(counted(scan, [6]))
    old = old.model_copy(update={"rows": [old.rows[0].model_copy(update={"distribution": None})]})
    merged = merge_counts([as_read(counted(scan, [0])), old])
    assert merged.total.interval is None
    assert merged.total.estimate == sum(plant.estimate for plant in merged.plants)
