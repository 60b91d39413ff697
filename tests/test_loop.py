"""The loop online: a simulation stepped by hand flies as `fly` does, replans without a jump, and its camera
renders the frames a batch render gives, so an online run writes the batch run's files and counts."""

from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
from conftest import fly_demo_raster

from renderloop.config import load_config
from renderloop.counting.cluster import CLASSES, class_points, count_rows
from renderloop.counting.online import OnlineCounter
from renderloop.errors import UserError
from renderloop.loop.reference import quintic_bridge
from renderloop.loop.simulation import Simulation
from renderloop.pipeline import run_pipeline
from renderloop.rundir import files, names
from renderloop.io.ownership import BOOKKEEPING
from renderloop.scene.model import read_scene
from renderloop.sim.flight import Reference, fly


@pytest.fixture(scope="module")
def flown(tmp_path_factory) -> Path:
    return fly_demo_raster(tmp_path_factory.mktemp("loop") / "run")


def test_a_simulation_stepped_by_hand_logs_the_flight_fly_logs(flown: Path):
    config = files.read_config(flown)
    table = files.read_trajectory(flown)
    reference = Reference(table[:, 0], table[:, 1:8], table[:, 8:15], table[:, 15:22])
    batch = fly(mujoco.MjModel.from_xml_path(str(flown / names.WORLD)), config, reference)
    with Simulation(config, flown) as sim:
        sim.follow(sim.scan_trajectory())
        sim.run_until(3.0)  # in pieces of every size: the flight may not depend on how it is stepped
        for _ in range(17):
            sim.step()
        sim.run()
        online = sim.log()
    for field in ("t", "position", "quaternion", "joints", "rotor_speeds", "reference", "camera_position", "contacts", "saturated"):
        assert np.array_equal(getattr(online, field), getattr(batch, field)), field


def test_the_quintic_bridge_meets_both_states_exactly():
    rng = np.random.default_rng(3)
    start, end = tuple(rng.normal(size=(3, 7))), tuple(rng.normal(size=(3, 7)))
    q, qd, qdd = quintic_bridge(start, end, 0.2, np.array([0.0, 0.2]))
    for got, want in zip((q, qd, qdd), zip(start, end)):
        assert np.allclose(got, np.array(want), atol=1e-9)


def test_a_replan_mid_flight_joins_without_a_jump_and_is_flown_safely(flown: Path):
    config = files.read_config(flown)
    with Simulation(config, flown) as sim:
        sim.follow(sim.scan_trajectory())
        sim.run_until(4.0)
        old = sim.plan.q.copy(), sim.plan.qd.copy(), sim.plan.qdd.copy()
        join = sim.tick
        here, velocity, _ = sim.reference
        behind = -0.5 * velocity[:3] / np.linalg.norm(velocity[:3])  # back where it came from: it must turn round
        target = here + np.concatenate([behind + [0.0, 0.0, 0.1], [0.4, 0.0, 0.0, 0.1]])
        [end] = sim.replan(np.array([target]))
        plan = sim.plan
        for before, after in zip(old, (plan.q, plan.qd, plan.qdd)):
            assert np.array_equal(before[: join + 1], after[: join + 1])  # the past, and the join itself, unchanged
        dt = 1 / sim.rate_hz
        window = slice(join, join + int(0.6 * sim.rate_hz))
        # the derivatives are the derivatives: q̇ integrates to q and q̈ to q̇ across the blend (trapezoid rule)
        assert np.allclose(np.diff(plan.q[window], axis=0), dt * (plan.qd[window][1:] + plan.qd[window][:-1]) / 2, atol=2e-4)
        assert np.allclose(np.diff(plan.qd[window], axis=0), dt * (plan.qdd[window][1:] + plan.qdd[window][:-1]) / 2, atol=3e-3)
        assert np.allclose(plan.q[-1], target, atol=1e-6) and end == pytest.approx(plan.t[-1] - sim.hold, abs=dt)
        limits = np.asarray(config.planner.acceleration_limits)
        assert np.all(np.abs(plan.qdd[join:]) <= 2 * limits)  # the bridge eases between two accelerations within the limits
        sim.run()
        log = sim.log()
    assert log.contacts.sum() == 0
    assert np.linalg.norm(log.position[-1] - target[:3]) < 0.05


def test_bad_sensor_arguments_are_value_errors_with_the_clis_sentence(flown: Path):
    config = files.read_config(flown)
    with Simulation(config, flown) as sim:
        with pytest.raises(ValueError, match="the control loop at 100.0 Hz cannot serve it"):
            sim.add_camera(rate_hz=1000.0)
        with pytest.raises(ValueError, match="unknown backend 'opengl'"):
            sim.add_camera(backend="opengl")
        with pytest.raises(ValueError, match="--address 127.0.0.1:1: no Ray cluster answers there"):
            sim.add_camera(executor="ray", address="127.0.0.1:1")
    assert issubclass(UserError, ValueError)


@pytest.mark.parametrize("encode", [False, True])
def test_a_raster_frame_reads_its_images_as_its_files_hold_them_and_a_released_frame_is_gone(flown: Path, encode: bool):
    """Files compressed ahead on the camera's thread (`encode`) or when first asked for: the same bytes either way."""
    from renderloop.loop.sensors import Frame
    from renderloop.render.frames import encode_images

    config = files.read_config(flown)
    with Simulation(config, flown) as sim:
        sim.follow(sim.scan_trajectory())
        camera = sim.add_camera(rate_hz=2.0, backend="raster", encode=encode)
        sim.run_until(1.6)
        frames = camera.frames_until(sim.t)
        assert len(frames) == 4 and all(frame.images for frame in frames)
        assert all((frame.encoded is not None) == encode for frame in frames)
        for frame in frames:  # the images this process kept are what the PNGs written from them decode to
            assert frame.files == encode_images(frame.images)
            from_files = Frame(frame.index, frame.timestamp, frame.pose, encoded=frame.files)
            for image in ("rgb", "depth", "ideal_rgb", "ideal_depth", "mask"):
                kept, decoded = getattr(frame, image), getattr(from_files, image)
                assert kept.dtype == decoded.dtype and np.array_equal(kept, decoded), image
        camera.release(1)
        assert [frame.index for frame in camera.frames_until(sim.t)] == [0, 2, 3]
        with pytest.raises(UserError, match="camera frame 1 was released"):
            camera.frame(1)


def test_perception_on_its_own_thread_feeds_the_counter_what_perception_in_line_does(flown: Path, monkeypatch):
    """Frames submitted faster than the thread perceives them (at most MAX_PERCEIVING wait) and collected whenever:
    the same detections, in frame order, and the same counts as each frame perceived at once."""
    from renderloop.loop import perceive
    from renderloop.loop.perceive import OnlinePerception

    monkeypatch.setattr(perceive, "MAX_PERCEIVING", 2)
    config = files.read_config(flown)
    with Simulation(config, flown) as sim:
        sim.follow(sim.scan_trajectory())
        camera = sim.add_camera(rate_hz=5.0, backend="raster")
        sim.run_until(6.0)  # the first seconds of the scan reach the plants
        frames = camera.frames_until(sim.t)
        in_line = OnlinePerception(config, OnlineCounter(sim.scene, config.counting, config.seed))
        for frame in frames:
            in_line.take(frame)
        with OnlinePerception(config, OnlineCounter(sim.scene, config.counting, config.seed), thread=True) as threaded:
            for k, frame in enumerate(frames):
                threaded.submit(frame)
                assert len(threaded._pending) <= 2
                if k % 3 == 2:
                    threaded.collect(wait=False)
            threaded.collect(wait=True)
    assert len(frames) == 30 and any(found.detections for found in in_line.frames)
    assert [found.index for found in threaded.frames] == list(range(30))
    assert threaded.frames == in_line.frames
    assert threaded.counter.counts().per_plant() == in_line.counter.counts().per_plant()


def _contract(run_dir: Path) -> dict[str, bytes]:
    """A run's files, less what says how it was run (its config, its seconds, its own bookkeeping)."""
    skip = {names.CONFIG, names.TIMINGS, *BOOKKEEPING}
    return {p.relative_to(run_dir).as_posix(): p.read_bytes() for p in sorted(run_dir.rglob("*"))
            if p.is_file() and p.name not in skip}


def test_an_online_run_writes_the_batch_runs_files_and_counts(complete_run: Path, tmp_path: Path):
    batch = files.read_config(complete_run)
    online = batch.override({"mission": {"online": True}})
    run_dir = tmp_path / "online"
    run_pipeline(run_dir, online)
    assert _contract(run_dir) == _contract(complete_run)
    assert files.read_counts(run_dir) == files.read_counts(complete_run)
    assert (run_dir / "rgb" / "000000.png").is_file()


def test_the_online_counter_counts_what_the_batch_count_counts(complete_run: Path):
    config = files.read_config(complete_run)
    detections = files.read_detections(complete_run, len(files.read_poses(complete_run)[0]))
    counter = OnlineCounter(read_scene(complete_run), config.counting, config.seed)
    for frame in reversed(detections.frames):  # arrival order does not matter: frames are counted in index order
        counter.add(frame)
    counted = counter.counts()
    recorded = files.read_counts(complete_run)
    assert counted.per_plant() == {p.id: p.estimate for p in recorded.plants if p.estimate}
    assert counted.total("unripe") == recorded.total.unripe_estimate
    # each fruit with the support of the batch count's cluster: the detections behind it (a cluster may hold fewer
    # than min_views of them where some of its points are only the resampling's copies of a detection)
    points = class_points(sorted(detections.frames, key=lambda frame: frame.index), config.counting.eps)
    batch = [(label, int(plant), int(support)) for label in CLASSES
             for row in count_rows(read_scene(complete_run), points[label], label, config.counting, config.seed)
             for plant, support in zip(row.plants, row.clusters.support())]
    assert [(fruit.label, fruit.plant, fruit.support) for fruit in counted.fruit] == batch
    assert sum(fruit.support for fruit in counted.fruit) <= sum(len(frame.detections) for frame in detections.frames)


@pytest.mark.parametrize("workers", [2])
def test_one_and_two_cycles_workers_render_the_same_online_frames(workers: int, tmp_path: Path):
    config = load_config("demo").override({"camera": {"width": 64, "height": 48, "rate_hz": 0.04},  # four frames of the 86 s scan
                                           "renderer": {"backend": "cycles"}})
    one = tmp_path / "one"
    with Simulation(config, one) as sim:
        sim.follow(sim.scan_trajectory())
        camera = sim.add_camera()
        sim.run()
        single = [frame.files for frame in camera.frames_until(sim.end)]
    two = tmp_path / "two"
    shutil.copytree(one, two)
    with Simulation(config, two) as sim:
        sim.follow(sim.scan_trajectory())
        camera = sim.add_camera(workers=workers)
        sim.run()
        several = [frame.files for frame in camera.frames_until(sim.end)]
    assert len(single) >= 3 and single == several


def test_online_cycles_sensor_frames_blurred_by_the_flown_motion_are_the_batch_renders(tmp_path: Path):
    """A sensor frame is asked for once its exposure has been flown and blurred over the motion the batch render
    reads from flight.csv: the online camera's files are the batch render's, byte for byte."""
    from renderloop.render.motion import FlownStates, frames_motion
    from renderloop.render.stage import run_render
    from renderloop.sim.flight import camera_frames
    from renderloop.sim.stage import write_flight

    config = load_config("demo").override({"camera": {"width": 64, "height": 48, "rate_hz": 0.1, "sensor": {"enabled": True}},
                                           "renderer": {"backend": "cycles", "samples": 1}})
    run_dir = tmp_path / "run"
    with Simulation(config, run_dir) as sim:
        sim.follow(sim.scan_trajectory())
        camera = sim.add_camera()
        sim.step()
        assert len(camera) == 1 and not camera.ready(0)  # taken at the first tick, its shutter still open
        sim.run()
        online = [frame.files for frame in camera.frames_until(sim.end)]
        shutters = np.array([camera.shutters[index] for index in range(len(online))])
        log = sim.log()
        write_flight(run_dir, config, log, camera_frames(log, sim.end, camera.rate_hz))
    times, poses = files.read_poses(run_dir)
    batch = frames_motion(FlownStates.of_flight(files.read_flight(run_dir)), config.robot.arm, times, poses,
                          config.camera.sensor, config.seed)
    assert np.array_equal(shutters, batch)  # the poses the shutter opened and closed at, to the bit
    assert np.linalg.norm(shutters[:, 1, :3, 3] - shutters[:, 0, :3, 3], axis=1).max() > 1e-3  # a frame in motion
    run_render(run_dir, config, force=True)
    assert len(online) >= 3 and all(names.RGB_SENSOR in frame for frame in online)
    for index, frame in enumerate(online):
        for stream, png in frame.items():
            assert (run_dir / names.frame_file(stream, index)).read_bytes() == png, (stream, index)


def test_a_replan_after_the_hover_starts_from_where_the_robot_rests(flown: Path):
    config = files.read_config(flown)
    with Simulation(config, flown, hold=0.2) as sim:
        sim.follow(sim.scan_trajectory())
        sim.run()
        for _ in range(30):  # past the end of the plan and its hover
            sim.step()
        rest = sim.reference[0].copy()
        sim.replan(np.array([rest + [0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0]]))
        assert len(sim.plan.t) > sim.tick and np.array_equal(sim.plan.q[sim.tick], rest)
        assert np.allclose(np.diff(sim.plan.t), 1 / sim.rate_hz)
