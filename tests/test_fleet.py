"""A compartment's scan split by rows (`mission.split: rows`): one mission a line, each a run of its own and a task of
the executor, the rows' counts merged and shared out among the UAVs without two in one path at once.

The compartment is the `commercial` preset cut to one plant a line and tiny raster frames, so that its four
missions run in seconds; its lines, paths and the planner's rules are the preset's."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest
import yaml

from renderloop.config import load_config
from renderloop.counting.summary import truth_counts
from renderloop.errors import UserError
from renderloop.fleet.compartment import row_dir_of, run_compartment
from renderloop.io.ownership import LEDGER, read_ledger
from renderloop.parallel import Executor
from renderloop.rundir import files, names
from renderloop.rundir.models import Harvest, Schedule
from renderloop.scene.model import read_scene

from conftest import cli

SMALL = {"greenhouse": {"size": [6.1, 5.0, 3.0], "table_size": [0.3, 0.4, 0.1], "plants_per_table": 1,
                        "workstation_center": [0.0, -2.1], "environment": {"kind": "plain"}},
         "plants": {"prototypes": 2, "peppers": {"per_side": [1, 2]}},
         "planner": {"bands": 1, "points_per_ellipse": 4},
         "camera": {"width": 96, "height": 72, "rate_hz": 0.2},
         "renderer": {"backend": "raster"}}
# Written by `renderloop run` with the seconds each stage took (the report shows them): the only wall-clock values.
CLOCKED = {names.TIMINGS, names.REPORT}


def _contents(directory: Path) -> dict[str, str]:
    """Every file below `directory` but the clocked ones, by path and sha1; each ledger as the set of files it lists
    (it lists them in the order they were written, which is the order the workers finished in); each config as what
    it computes (a worker renders on its share of the cores: `renderer.threads`)."""
    found = {}
    for path in sorted(directory.rglob("*")):
        if not path.is_file() or path.name in CLOCKED:
            continue
        name = path.relative_to(directory).as_posix()
        if path.name == LEDGER:
            found[name] = ",".join(sorted(read_ledger(path.parent)))
        elif path.name == names.CONFIG:
            found[name] = files.read_config(path.parent).override({"renderer": {"threads": 0}}).to_yaml()
        else:
            found[name] = hashlib.sha1(path.read_bytes()).hexdigest()
    return found


@pytest.fixture(scope="module")
def small():
    return load_config("commercial").override(SMALL)


@pytest.fixture(scope="module")
def compartment(small, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("fleet") / "house"
    run_compartment(out, small)
    return out


def test_every_line_of_the_compartment_is_a_run_of_its_own_scanning_that_line(compartment: Path):
    scene = read_scene(compartment)
    assert sorted(p.name for p in (compartment / names.ROW_RUNS).iterdir()) == [f"row_{r.id}" for r in scene.rows]
    for row in scene.rows:
        run_dir = row_dir_of(compartment, row.id)
        config = files.read_config(run_dir)
        assert config.planner.row == row.id and config.mission.split == "none"
        assert (run_dir / names.SCENE).read_bytes() == (compartment / names.SCENE).read_bytes()
        counted = files.read_counts(run_dir)
        assert [r.id for r in counted.rows] == [row.id] and {p.id for p in counted.plants} == set(row.plants)
        assert (run_dir / names.REPORT).is_file()


def test_the_compartments_count_is_its_lines_counts_added_up_against_the_whole_truth(compartment: Path):
    scene, merged = read_scene(compartment), files.read_counts(compartment)
    rows = [files.read_counts(row_dir_of(compartment, row.id)) for row in scene.rows]
    truth = truth_counts(scene)
    assert merged.total.truth == sum(t["ripe"] for t in truth.values()) == sum(r.total.truth for r in rows) > 0
    assert merged.total.estimate == sum(r.total.estimate for r in rows)
    assert merged.rows == [r.rows[0] for r in rows]
    assert merged.detections.frames == sum(r.detections.frames for r in rows)
    low, high = merged.total.interval.low, merged.total.interval.high
    assert sum(r.total.interval.low for r in rows) <= high and low <= sum(r.total.interval.high for r in rows)
    harvest = files.read_model(compartment / names.HARVEST, Harvest)
    chosen = {p.id for p in merged.plants if p.estimate >= 1}
    assert {stop.id for stop in harvest.stops} == chosen  # one tour through the plants of every line


def test_the_fleet_never_flies_two_uavs_in_one_path_at_once(compartment: Path):
    plan = Schedule.model_validate(json.loads((compartment / names.FLEET).read_text()))
    by_row = {flight.row: flight for flight in plan.flights}
    assert sorted(by_row) == [0, 1, 2, 3] and {f.uav for f in plan.flights} == {0, 1}
    inner_west, inner_east = by_row[1], by_row[2]  # the two lines either side of the middle path, scanned from it
    assert inner_west.end_s <= inner_east.start_s or inner_east.end_s <= inner_west.start_s
    for flight in plan.flights:  # each mission flies as long as its row's run flew
        flown = files.read_flight(row_dir_of(compartment, flight.row))["t"][-1]
        assert flight.end_s - flight.start_s == pytest.approx(flown, abs=0.01)
    assert plan.makespan_s < sum(f.end_s - f.start_s for f in plan.flights)  # two UAVs, shorter than one


def test_a_compartment_on_a_two_worker_ray_cluster_gives_the_files_of_one_process(compartment: Path, small, tmp_path: Path):
    out = tmp_path / "house"
    run_compartment(out, small, executor=Executor(kind="ray", workers=2))
    made, expected = _contents(out), _contents(compartment)
    assert made == expected, sorted(k for k in made.keys() | expected.keys() if made.get(k) != expected.get(k))


def test_a_killed_compartment_resumes_its_unfinished_line_and_leaves_the_finished_ones(compartment: Path, small,
                                                                                        tmp_path: Path):
    out = Path(shutil.copytree(compartment, tmp_path / "house"))
    unfinished = row_dir_of(out, 2)
    for name in (names.DETECTIONS, names.DETECTION_SCORES, names.COUNTS):  # killed while detecting
        (unfinished / name).unlink(missing_ok=True)
    (out / names.COUNTS).unlink()
    finished = {path: path.stat().st_mtime_ns for row in (0, 1, 3) for path in row_dir_of(out, row).rglob("*.png")}
    run_compartment(out, small)
    assert {path: path.stat().st_mtime_ns for path in finished} == finished
    assert _contents(out) == _contents(compartment)


def test_other_uavs_schedule_a_scanned_compartment_again_without_running_its_lines_again(compartment: Path, small,
                                                                                          tmp_path: Path):
    out = Path(shutil.copytree(compartment, tmp_path / "house"))
    frames = {path: path.stat().st_mtime_ns for path in (out / names.ROW_RUNS).rglob("*.png")}
    run_compartment(out, small.override({"mission": {"uavs": 1}}))
    plan = Schedule.model_validate(json.loads((out / names.FLEET).read_text()))
    assert {flight.uav for flight in plan.flights} == {0} and plan.makespan_s == pytest.approx(
        sum(f.end_s - f.start_s for f in plan.flights), abs=0.01)  # one UAV flies every line, one after another
    assert files.read_config(out).mission.uavs == 1
    assert {path: path.stat().st_mtime_ns for path in frames} == frames
    assert files.read_counts(out) == files.read_counts(compartment)
    with pytest.raises(UserError, match=r"made with another config \(camera.rate_hz"):  # what the lines' files follow
        run_compartment(out, small.override({"camera": {"rate_hz": 0.5}}))


def test_one_line_of_the_compartment_is_scanned_counted_and_scored_alone(small, tmp_path: Path, monkeypatch, capsys):
    config = tmp_path / "one_line.yaml"
    config.write_text(yaml.safe_dump({**SMALL, "planner": {**SMALL["planner"], "row": 1}}))
    out = tmp_path / "house"
    code, stdout, err = cli(monkeypatch, capsys, "run", "--preset", "commercial", "--config", str(config), "--out", str(out))
    assert code == 0, err
    assert [p.name for p in (out / names.ROW_RUNS).iterdir()] == ["row_1"]
    counted, scene = files.read_counts(out), read_scene(out)
    assert [r.id for r in counted.rows] == [1]
    assert counted.total.truth == sum(p.ripe for p in scene.peppers if scene.plant(p.plant).row == 1)
    assert f"report: {out / names.ROW_RUNS / 'row_*' / names.REPORT}" in stdout


@pytest.mark.parametrize("change, message", [
    ({"mission": {"split": "none", "uavs": 2}}, "mission.uavs: 2 UAVs share a scan split by rows; set mission.split: rows"),
    ({"planner": {"row": 7}}, "planner.row: the greenhouse has 4 rows (0 to 3), not 7"),
])
def test_a_fleet_the_compartment_cannot_have_is_refused_in_one_line(change, message, tmp_path: Path, monkeypatch, capsys):
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump({**SMALL, **change}))
    code, _, err = cli(monkeypatch, capsys, "run", "--preset", "commercial", "--config", str(config),
                       "--out", str(tmp_path / "house"))
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "house").exists()


def test_a_ray_address_that_does_not_answer_is_one_line_before_any_row_runs(tmp_path: Path, monkeypatch, capsys):
    config = tmp_path / "small.yaml"
    config.write_text(yaml.safe_dump(SMALL))
    code, _, err = cli(monkeypatch, capsys, "run", "--preset", "commercial", "--config", str(config), "--out",
                       str(tmp_path / "house"), "--executor", "ray", "--address", "127.0.0.1:9")
    assert code == 2 and "no Ray cluster answers there" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "house").exists()


def test_planning_a_split_compartment_as_one_mission_is_refused_in_one_line(compartment: Path, tmp_path: Path,
                                                                            monkeypatch, capsys):
    out = Path(shutil.copytree(compartment, tmp_path / "house"))
    code, _, err = cli(monkeypatch, capsys, "plan", str(out))
    assert code == 2 and "renderloop run` plans each row's mission in rows/row_<id>" in err
    assert len(err.strip().splitlines()) == 1 and not (out / names.WAYPOINTS).exists()
