from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from renderloop.config import load_config
from renderloop.io.csvtable import read_csv
from renderloop.io.tum import read_tum
from renderloop.planning.stage import run_plan
from renderloop.planning.waypoints import read_waypoints, scan_target
from renderloop.rundir import names
from renderloop.rundir.files import FLIGHT_HEADER, read_trajectory
from renderloop.scene.model import load_scene, read_scene
from renderloop.scene.stage import run_scene
from renderloop.scene.world import world_xml
from renderloop.sim import corridor
from renderloop.sim.corridor import corridor_xml
from renderloop.sim.flight import Flight, Reference, fly

HOVER = np.array([0.0, -1.2, 1.0, 0.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def flight(demo) -> Flight:
    config, scene = demo
    return Flight(mujoco.MjModel.from_xml_string(world_xml(scene, config)), config, seed=0)


def hold(flight: Flight, start: np.ndarray, target: np.ndarray, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """Start at rest at `start`, command a constant `target`; returns (time, q* actually flown)."""
    flight.reset(start)
    rows, zero = [], np.zeros(7)
    for _ in range(int(seconds / flight.dt)):
        flight.tick(target, zero, zero)
        data = flight.data
        yaw = Rotation.from_quat(data.qpos[[4, 5, 6, 3]]).as_euler("ZYX")[0]
        rows.append([*data.qpos[:3], yaw, *data.qpos[flight.joint_qpos]])
    return np.arange(1, len(rows) + 1) * flight.dt, np.array(rows)


def test_paper_closed_loop_tracks_the_planned_camera_path(paper_run):
    _, run_dir = paper_run
    table = read_csv(run_dir / "flight.csv", FLIGHT_HEADER)
    camera_error = table[:, FLIGHT_HEADER.index("cam_err")]
    assert np.sqrt(np.mean(camera_error**2)) <= 0.03
    assert camera_error.max() <= 0.10
    assert table[:, FLIGHT_HEADER.index("contacts")].sum() == 0
    assert table[:, FLIGHT_HEADER.index("saturated")].mean() <= 0.01


def test_hover_holds_altitude_within_a_centimetre(flight):
    start = HOVER + np.array([0.1, -0.1, -0.2, 0.2, 0, 0, 0])
    t, flown = hold(flight, start, HOVER, 12.0)
    settled = t > 5.0
    assert np.abs(flown[settled, 2] - HOVER[2]).max() < 0.01
    assert np.abs(flown[settled, :2] - HOVER[:2]).max() < 0.01


@pytest.mark.parametrize(
    ("axis", "step"),
    [(0, 0.5), (1, -0.5), (2, 0.3), (3, 0.8), (4, 0.3), (5, -0.3), (6, 0.4)],
    ids=["x", "y", "z", "yaw", "q1", "q2", "q3"],
)
def test_each_loop_settles_without_sustained_oscillation(flight, axis, step):
    target = HOVER.copy()
    target[axis] += step
    t, flown = hold(flight, HOVER, target, 10.0)
    error = (target[axis] - flown[:, axis]) / step
    assert -error.min() < 0.25  # overshoot below 25 %
    late = t > 6.0
    assert np.abs(error[late]).max() < 0.02  # settled within 2 %
    assert np.ptp(error[late]) < 0.01  # and still: no sustained oscillation


def test_attitude_loops_level_a_tilted_start(flight):
    flight.reset(HOVER)
    flight.data.qpos[3:7] = np.roll(Rotation.from_euler("xyz", [0.35, -0.3, 0.0]).as_quat(), 1)  # 26 degrees
    mujoco.mj_forward(flight.model, flight.data)
    tilts, zero = [], np.zeros(7)
    for _ in range(400):
        flight.tick(HOVER, zero, zero)
        tilts.append(math.degrees(math.acos(min(1.0, flight.body_rotation()[2, 2]))))
    assert tilts[19] < 5.0  # the attitude loops level it within 0.2 s
    assert max(tilts[300:]) < 0.5  # then the position loops fly it back and it stays level
    assert np.abs(flight.data.qpos[:3] - HOVER[:3]).max() < 0.01


def test_scan_frames_look_at_their_plant(paper_run):
    config, run_dir = paper_run
    scene = load_scene(run_dir / "scene.json")
    times, positions, rotations = read_tum(run_dir / "groundtruth.txt")
    assert np.allclose(np.diff(times), 1.0 / config.camera.rate_hz)
    waypoints = read_waypoints(run_dir)
    checked = 0
    for before, after in zip(waypoints[:-1], waypoints[1:]):
        if not (before.kind == after.kind == "scan" and before.plant == after.plant):
            continue
        target = scan_target(scene.plant(before.plant))
        for k in np.flatnonzero((times >= before.time) & (times <= after.time)):
            to_plant = target - positions[k]
            angle = math.degrees(math.acos(rotations[k][:, 2] @ to_plant / np.linalg.norm(to_plant)))
            assert angle < 15.0 and 0.3 <= np.linalg.norm(to_plant) <= 1.0
            checked += 1
    assert checked > 1000


def test_groundtruth_is_the_flown_camera(paper_run):
    _, run_dir = paper_run
    times, positions, rotations = read_tum(run_dir / "groundtruth.txt")
    table = read_csv(run_dir / "flight.csv", FLIGHT_HEADER)
    rows = np.searchsorted(table[:, 0], times - 1e-9)
    assert np.allclose(table[rows, 0], times)
    assert np.allclose(table[rows, 26:29], positions, atol=2e-6)
    assert np.allclose(np.linalg.det(rotations), 1.0)


def test_position_noise_is_seeded(demo, tmp_path):
    config, scene = demo
    noisy = config.override({"controller": {"position_noise_std": 0.01}})
    model = mujoco.MjModel.from_xml_string(world_xml(scene, noisy))

    def flown(seed: int) -> np.ndarray:
        aircraft = Flight(model, noisy, seed)
        aircraft.reset(HOVER)
        for _ in range(200):
            aircraft.tick(HOVER, np.zeros(7), np.zeros(7))
        return aircraft.data.qpos.copy()

    assert np.array_equal(flown(1), flown(1))
    assert not np.array_equal(flown(1), flown(2))
    assert np.abs(flown(1)[:3] - HOVER[:3]).max() < 0.05


# three rows of two plants 3.4 m apart (the greenhouse preset's pitch), the middle one scanned
ROWS = {"greenhouse": {"size": [10.2, 6.0, 3.0], "tables": [[-3.4, 0.0], [0.0, 0.0], [3.4, 0.0]], "table_size": [0.3, 1.0, 0.1],
                       "plants_per_table": 2, "workstation_center": [-3.4, -2.65]},
        "planner": {"row": 1, "bands": 1, "points_per_ellipse": 4}}


def test_a_flight_in_its_paths_corridor_is_the_whole_worlds_flight_to_the_bit(tmp_path, monkeypatch):
    config = load_config("greenhouse", seed=0).override(ROWS)
    run_scene(tmp_path, config)
    run_plan(tmp_path, config)
    table, world = read_trajectory(tmp_path), tmp_path / names.WORLD
    reference = Reference(table[:, 0], table[:, 1:8], table[:, 8:15], table[:, 15:22])
    text, kept, dropped = corridor_xml(world, reference.q[:, :3])
    left = mujoco.MjModel.from_xml_string(text)
    plants = {f"plant_{plant.id}": plant.position[0] for plant in read_scene(tmp_path).plants}
    names_left = {left.geom(i).name for i in range(left.ngeom)}
    assert {name for name, x in plants.items() if name in names_left} == {name for name, x in plants.items() if x == 0.0}
    assert left.ngeom == kept and dropped > 0
    whole = fly(mujoco.MjModel.from_xml_path(str(world)), config, reference)
    fields = ("position", "quaternion", "joints", "rotor_speeds", "camera_position", "contacts", "saturated")
    flown = []  # the worlds each flight is flown in
    monkeypatch.setattr(corridor, "fly", lambda model, *args: flown.append(model.ngeom) or fly(model, *args))
    in_corridor = corridor.fly_in_corridor(world, config, reference)
    assert flown == [kept] and all(np.array_equal(getattr(in_corridor, f), getattr(whole, f)) for f in fields)
    # a flight that strays from its plan farther than the margin is flown again in the whole world
    monkeypatch.setattr(corridor, "MARGIN", 0.0)
    corridor.fly_in_corridor(world, config, reference)
    assert flown[-1] == kept + dropped and len(flown) == 3
