"""The adaptive mission: a coarse pass, then views chosen where the count is uncertain, flown by replanning; what it
decided is in mission.json, the same for a seed, and a mission that cannot look again says why."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import cli, fly_demo_raster

from renderloop.config import Config, IntervalConfig, deep_merge, load_config
from renderloop.counting.stage import run_count
from renderloop.counting.summary import run_counting
from renderloop.loop.simulation import Simulation
from renderloop.loop.viewpoints import View, camera_position
from renderloop.pipeline import run_pipeline
from renderloop.rundir import files, names
from renderloop.io.ownership import BOOKKEEPING
from renderloop.scene.model import read_scene

# Two plants on the demo table, raster frames, a first pass every 5 s and one round of two views: a mission in seconds
# (and a static scan at 0.5 Hz beside it). A cautious prior on the unseen canopy keeps every plant open after the first
# pass, so that the mission looks again.
SMALL = {"renderer": {"backend": "raster"}, "greenhouse": {"plants_per_table": 2}, "camera": {"rate_hz": 0.5},
         "counting": {"interval": {"hidden_unseen": 4.0}},
         "mission": {"kind": "adaptive", "adaptive": {"first_pass_rate_hz": 0.2, "views_per_round": 2, "rounds": 1}}}


def _config(**adaptive: float) -> Config:
    return load_config("demo").override(SMALL).override({"mission": {"adaptive": adaptive}})


@pytest.fixture(scope="module")
def adaptive_run(tmp_path_factory) -> Path:
    run_dir = tmp_path_factory.mktemp("mission") / "run"
    run_pipeline(run_dir, _config())
    return run_dir


def _contract(run_dir: Path) -> dict[str, bytes]:
    skip = {names.CONFIG, names.TIMINGS, *BOOKKEEPING}
    return {p.relative_to(run_dir).as_posix(): p.read_bytes() for p in sorted(run_dir.rglob("*"))
            if p.is_file() and p.name not in skip}


def test_the_mission_looks_again_at_uncertain_plants_from_the_views_it_logs(adaptive_run: Path):
    mission = files.read_mission(adaptive_run)
    scene = read_scene(adaptive_run)
    times, poses = files.read_poses(adaptive_run)
    counts = files.read_counts(adaptive_run)
    views = [(plant, view) for plant in mission.plants for r in plant.rounds for view in r.views]
    assert views, "the first pass at 0.2 Hz leaves plants uncertain: the mission must look again"
    assert mission.frames == len(times) == counts.detections.frames
    assert mission.first_pass_frames == mission.frames - len(views)
    for plant, view in views:
        assert view.frame is not None and times[view.frame] >= view.time - 1e-9
        wanted = camera_position(scene.plant(plant.id), View(view.azimuth, view.height, view.distance))
        assert np.linalg.norm(poses[view.frame][:3, 3] - wanted) < 0.05  # the camera was where the view is, give or take tracking
        assert (adaptive_run / names.frame_file(names.RGB, view.frame)).is_file()
    for plant in mission.plants:
        assert plant.final.low <= plant.final.estimate <= plant.final.high or plant.final.weak
        for r in plant.rounds:
            assert r.before.high - r.before.low > 0 and "interval" in r.why  # only an uncertain plant is looked at again


def test_an_adaptive_runs_count_takes_the_missions_interval_and_lone_credit_and_a_static_run_the_countings(
        adaptive_run: Path, tmp_path: Path):
    run_dir = tmp_path / "run"
    shutil.copytree(adaptive_run, run_dir)
    detections = files.read_detections(run_dir, len(files.read_poses(run_dir)[1]))
    sparse = [frame if frame.index % 3 == 0 else frame.model_copy(update={"detections": []})  # a sparse scan sees
              for frame in detections.frames]  # fruit once: the detections of every third frame alone
    files.write_model(run_dir / names.DETECTIONS, detections.model_copy(update={"frames": sparse}))
    wide = IntervalConfig(hidden=3.0)  # about three hidden fruit a plant: no interval can be the estimate alone
    config = _config().override({"mission": {"adaptive": {"interval": wide, "lone_credit": 1.0}}})
    assert run_counting(config).interval == wide and run_counting(config).lone_credit == 1.0
    static = config.override({"mission": {"kind": "static"}})
    assert run_counting(static) == config.counting == _config().counting
    run_count(run_dir, config, force=True)
    counts = files.read_counts(run_dir)
    assert counts.settings["interval"]["hidden"] == 3.0
    assert all(plant.interval.high > plant.estimate for plant in counts.plants)
    assert all(plant.estimate == len(plant.clusters) + len(plant.seen_once) for plant in counts.plants)
    assert sum(len(plant.seen_once) for plant in counts.plants) > 0  # fruit seen once, each credited 1.0
    assert files.read_counts(adaptive_run).settings["interval"]["hidden"] == _config().counting.interval.hidden


def test_the_harvest_plan_is_redrawn_at_each_decision_from_the_latest_counts(adaptive_run: Path):
    mission = files.read_mission(adaptive_run)
    min_ripe = files.read_config(adaptive_run).counting.harvest_min_ripe
    times = [update.time for update in mission.harvest]
    assert times == sorted(times)
    assert {plant.row for plant in mission.plants} == {update.row for update in mission.harvest if update.round == 0}
    assert {r.decided_at for plant in mission.plants for r in plant.rounds} <= set(times)  # each round's decision drew one
    assert [update.plants_counted for update in mission.harvest][-1] == len(mission.plants)
    latest = {plant.id: plant.rounds[-1].after.estimate if plant.rounds else plant.first_pass.estimate
              for plant in mission.plants}  # a round's `after` is read at the decision after it, which drew a plan
    chosen = sorted(pid for pid, ripe in latest.items() if ripe >= min_ripe)
    assert sorted(mission.harvest[-1].stops) == chosen
    assert mission.harvest[-1].expected_ripe == sum(latest[pid] for pid in chosen)


def test_the_mission_flies_its_views_without_touching_anything(adaptive_run: Path):
    flight = files.read_flight(adaptive_run)
    assert not np.any(flight["contacts"] > 0)
    assert files.read_mission(adaptive_run).flight_time_s > float(files.read_trajectory(adaptive_run)[-1, 0])


def test_a_mission_with_no_budget_flies_the_first_pass_alone_and_says_why(tmp_path: Path):
    run_dir = tmp_path / "no_budget"
    run_pipeline(run_dir, _config(budget_s=0.0))
    mission = files.read_mission(run_dir)
    assert mission.frames == mission.first_pass_frames and not any(plant.rounds for plant in mission.plants)
    uncertain = [plant for plant in mission.plants if plant.first_pass.low != plant.first_pass.high]
    assert uncertain and all("budget" in (plant.fallback or "") for plant in uncertain)


def test_a_refused_re_scan_path_drops_its_last_view_and_flies_the_rest(tmp_path: Path, monkeypatch):
    """A path through views each clear may still bend too near a plant: the mission tries again without its last
    view rather than giving up every view of the row."""
    from renderloop.errors import UserError

    replan, refusals = Simulation.replan, []

    def refuse_once(self, waypoints, check=False):
        if check and not refusals:
            refusals.append(len(waypoints))
            raise UserError("the trajectory comes within 3 cm of plant_1")
        return replan(self, waypoints, check)

    monkeypatch.setattr(Simulation, "replan", refuse_once)
    run_dir = tmp_path / "refused"
    run_pipeline(run_dir, _config())
    mission = files.read_mission(run_dir)
    assert refusals  # the first re-scan was refused
    flown = [view for plant in mission.plants for round_ in plant.rounds for view in round_.views]
    assert flown and mission.frames == mission.first_pass_frames + len(flown)
    assert all(plant.fallback is None for plant in mission.plants if plant.rounds)


def test_a_re_scan_path_that_clashes_on_the_way_to_a_view_drops_that_view_and_flies_the_others(
        adaptive_run: Path, tmp_path: Path, monkeypatch):
    from renderloop.planning.check import Clash

    replan, refusals = Simulation.replan, []

    def clash_at_the_first_view(self, waypoints, check=False):
        if check and not refusals:
            refusals.append(len(waypoints))
            raise Clash("the trajectory comes within 3 cm of plant_1", self.t, waypoint=0)
        return replan(self, waypoints, check)

    def views(run_dir: Path) -> list[tuple]:
        return sorted(((view.time, plant.id, view.azimuth, view.height, view.distance) for plant in files.read_mission(run_dir).plants
                       for round_ in plant.rounds for view in round_.views))

    monkeypatch.setattr(Simulation, "replan", clash_at_the_first_view)
    run_dir = tmp_path / "clash"
    run_pipeline(run_dir, _config())
    assert refusals
    unrefused = views(adaptive_run)
    assert len(unrefused) >= 2
    assert sorted(view[1:] for view in views(run_dir)) == sorted(view[1:] for view in unrefused[1:])  # the first flown view dropped


def test_the_report_shows_what_the_mission_decided(adaptive_run: Path, tmp_path: Path, monkeypatch, capsys):
    code, _, err = cli(monkeypatch, capsys, "report", str(adaptive_run), "--out", str(tmp_path / "report.html"))
    assert code == 0, err
    page = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert 'id="mission"' in page and "views the mission added" in page and "A coarse first pass took" in page


def test_eval_puts_both_missions_side_by_side_and_the_mission_is_the_same_for_a_seed(adaptive_run: Path, tmp_path: Path,
                                                                                       monkeypatch, capsys):
    config = tmp_path / "small.yaml"  # the mission's kind from the command line, its settings from the file
    config.write_text(yaml.safe_dump(deep_merge(SMALL, {"mission": {"kind": "static"}})))
    out = tmp_path / "eval"
    code, stdout, err = cli(monkeypatch, capsys, "eval", "--preset", "demo", "--config", str(config), "--seeds", "0",
                            "--mission", "static,adaptive", "--out", str(out))
    assert code == 0, err
    rows = (out / "eval.csv").read_text().splitlines()
    assert [row.split(",")[1] for row in rows[1:]] == ["static", "adaptive"]
    assert "| 0 | static |" in stdout and "| 0 | adaptive |" in stdout and "adaptive: mean absolute error" in stdout
    assert _contract(out / "seed_0_adaptive") == _contract(adaptive_run)  # flown again, frame for frame the same
    code, _, err = cli(monkeypatch, capsys, "eval", "--seeds", "0", "--mission", "greedy", "--out", str(tmp_path / "bad"))
    assert code == 2 and "--mission greedy: choose from static, adaptive" in err and len(err.strip().splitlines()) == 1


def test_the_camera_takes_a_frame_at_each_trigger_and_none_periodic_while_paused(tmp_path: Path):
    flown = fly_demo_raster(tmp_path / "run")
    config = files.read_config(flown)
    with Simulation(config, flown) as sim:
        sim.follow(sim.scan_trajectory())
        camera = sim.add_camera(rate_hz=1.0)
        camera.trigger(2.345)
        sim.run_until(1.5)
        camera.pause(until=5.5)  # from now: the periodic frames at 2, 3, 4 and 5 s are not taken
        camera.trigger(4.0)
        camera.trigger(6.0)  # at a periodic instant: one frame serves both
        sim.run_until(7.05)
        stamps = camera.timestamps
    assert stamps == pytest.approx([0.0, 1.0, 2.35, 4.0, 6.0, 7.0])  # a trigger waits for the control tick after it
