from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import toppra.algorithm

from renderloop.config import PlannerConfig, load_config
from renderloop.errors import UserError
from renderloop.io.csvtable import read_csv
from renderloop.planning.check import check_trajectory
from renderloop.planning.trajectory import time_parameterize
from renderloop.rundir.files import TRAJECTORY_HEADER
from renderloop.planning.waypoints import plan_waypoints, read_waypoints, scan_target
from renderloop.robot.kinematics import dofs_to_camera_pose, planned_camera_positions
from renderloop.scene.world import world_xml


@pytest.fixture(scope="module")
def trajectory(paper_run):
    config, run_dir = paper_run
    table = read_csv(run_dir / "trajectory.csv", TRAJECTORY_HEADER)
    return config, table, read_waypoints(run_dir)


def test_trajectory_header_and_rate(paper_run):
    _, run_dir = paper_run
    assert (run_dir / "trajectory.csv").read_text().splitlines()[0] == (
        "t,x,y,z,yaw,q1,q2,q3,dx,dy,dz,dyaw,dq1,dq2,dq3,ddx,ddy,ddz,ddyaw,ddq1,ddq2,ddq3"
    )
    table = read_csv(run_dir / "trajectory.csv", TRAJECTORY_HEADER)
    assert np.allclose(np.diff(table[:, 0]), 0.01)


def test_every_sample_within_the_limits_and_at_rest_at_both_ends(trajectory):
    config, table, _ = trajectory
    velocity, acceleration = table[:, 8:15], table[:, 15:22]
    assert np.all(np.abs(velocity).max(axis=0) <= 1.01 * np.array(config.planner.velocity_limits))
    assert np.all(np.abs(acceleration).max(axis=0) <= 1.01 * np.array(config.planner.acceleration_limits))
    assert np.allclose(velocity[0], 0) and np.allclose(velocity[-1], 0) and np.allclose(acceleration[-1], 0)
    assert np.allclose(table[0, 1:8], table[-1, 1:8] - [0, 0, 0, table[-1, 4] - table[0, 4], 0, 0, 0])  # back home


def test_passes_within_a_centimetre_of_every_waypoint(trajectory):
    _, table, waypoints = trajectory
    for waypoint in waypoints:
        assert np.linalg.norm(table[:, 1:4] - waypoint.dofs[:3], axis=1).min() < 0.01
        k = int(np.argmin(np.abs(table[:, 0] - waypoint.time)))  # and it is there when waypoints.csv says
        assert np.linalg.norm(table[k, 1:4] - waypoint.dofs[:3]) < 0.01


def test_yaw_has_no_wrap_jump(trajectory):
    config, table, _ = trajectory
    step_limit = 1.01 * config.planner.velocity_limits[3] * 0.01
    assert np.abs(np.diff(table[:, 4])).max() <= step_limit + 1e-9


def test_yaw_across_pi_turns_the_short_way():
    planner = PlannerConfig()
    waypoints = np.array([[0, 0, 1, 3.0, 0, 0, 0], [0.2, 0, 1, -3.0, 0, 0, 0]])
    result = time_parameterize(waypoints, planner)
    assert result.q[-1, 3] == pytest.approx(2 * math.pi - 3.0, abs=1e-6)
    assert result.q[:, 3].min() >= 3.0 - 1e-9  # 0.28 rad up through pi, not 6 rad down
    assert result.t[-1] < 5.0


def test_scan_waypoints_look_at_their_plant_from_both_sides(paper_run, trajectory):
    config, run_dir = paper_run
    from renderloop.scene.model import load_scene

    scene = load_scene(run_dir / "scene.json")
    _, _, waypoints = trajectory
    for plant in scene.plants:
        mine = [w for w in waypoints if w.kind == "scan" and w.plant == plant.id]
        assert sorted({w.side for w in mine}) == ["left", "right"]
        assert len(mine) == 2 * config.planner.points_per_ellipse
        for w in mine:
            pose = dofs_to_camera_pose(w.dofs, config.robot.arm)
            to_plant = scan_target(plant) - pose[:3, 3]
            assert math.degrees(math.acos(pose[:3, 2] @ to_plant / np.linalg.norm(to_plant))) < 1.0
            assert 0.3 <= np.linalg.norm(to_plant) <= 1.0
            assert abs(np.linalg.norm(w.dofs[:2] - scan_target(plant)[:2]) - config.planner.distance) < 0.2


def test_planned_camera_positions_match_forward_kinematics(trajectory):
    config, table, _ = trajectory
    rows = table[::997, 1:8]
    expected = np.array([dofs_to_camera_pose(q, config.robot.arm)[:3, 3] for q in rows])
    assert np.allclose(planned_camera_positions(rows, config.robot.arm), expected, atol=1e-12)


def test_coinciding_waypoints_are_refused():
    waypoints = np.array([[0, 0, 1, 0, 0, 0, 0], [1, 0, 1, 0, 0, 0, 0], [1, 0, 1, 0, 0, 0, 0]])
    with pytest.raises(UserError, match="waypoints 1 and 2 coincide"):
        time_parameterize(waypoints, PlannerConfig())


def test_toppra_failure_is_a_clear_error(monkeypatch):
    monkeypatch.setattr(toppra.algorithm.TOPPRA, "compute_trajectory", lambda self, *args: None)
    with pytest.raises(UserError, match="TOPP-RA found no feasible parameterisation"):
        time_parameterize(np.array([[0, 0, 1, 0, 0, 0, 0], [1, 0, 1, 0, 0, 0, 0]]), PlannerConfig())


@pytest.mark.parametrize("field", ["velocity_limits", "acceleration_limits"])
def test_zero_or_negative_limits_are_refused(tmp_path, field):
    for value in (0, -1):
        path = tmp_path / "limits.yaml"
        path.write_text(f"planner:\n  {field}: [1, 1, 1, 1, 1, 1, {value}]\n")
        with pytest.raises(UserError, match=f"planner.{field}"):
            load_config("paper", path)


def test_a_scene_without_plants_is_refused(paper):
    config, scene = paper
    with pytest.raises(UserError, match="no plants"):
        plan_waypoints(scene.model_copy(update={"plants": [], "rows": [], "peppers": []}), config)


def test_the_check_refuses_trajectories_that_leave_the_room_or_hit_a_table(paper):
    config, scene = paper
    model = mujoco.MjModel.from_xml_string(world_xml(scene, config))
    t = np.array([0.0, 0.1])
    outside = np.array([[0, -1.2, 1, 0, 0, 0, 0], [0, 6.5, 1, 0, 0, 0, 0]])
    with pytest.raises(UserError, match="leaves the greenhouse at t=0.10"):
        check_trajectory(model, t, outside, scene.room)
    table = scene.rows[0].table.center
    through = np.array([[0, -1.2, 1, 0, 0, 0, 0], [table[0], table[1], 0.7, 0, 0, 0, 0]])
    with pytest.raises(UserError, match=r"(table_0|pot_\d+|plant_\d+) at t=0.10"):
        check_trajectory(model, t, through, scene.room)


def test_take_off_point_by_a_wall_is_refused(paper):
    config, scene = paper
    by_the_wall = config.override({"robot": {"home": (5.9, 0.0, 0.0)}})
    with pytest.raises(UserError, match="transit start"):
        plan_waypoints(scene, by_the_wall)


def test_a_camera_pitch_the_arm_cannot_reach_is_a_planning_error(paper):
    config, scene = paper
    stiff = config.override({"robot": {"arm": {"joint_limits": (-0.2, 0.2)}}})
    with pytest.raises(UserError, match=r"cannot aim the camera at plant \d+: joint q3 = .* outside the limits"):
        plan_waypoints(scene, stiff)


def test_a_tall_canopy_is_scanned_in_bands_each_round_its_own_height_up_one_plant_and_down_the_next():
    from renderloop.scene.generate import generate_scene

    config = load_config("greenhouse").override({"plants": {"pepper_style": {"leaves": [20, 30]}}, "planner": {"bands": 3}})
    scene = generate_scene(config)
    arm, per = config.robot.arm, config.planner.points_per_ellipse
    first_line, walked = [], []
    for waypoint in plan_waypoints(scene, config):
        if waypoint.kind == "scan":
            if walked and (waypoint.side, waypoint.plant) != walked[-1] and waypoint.side != walked[0][0]:
                break
            walked.append((waypoint.side, waypoint.plant))
            first_line.append(dofs_to_camera_pose(waypoint.dofs, arm)[:3, 3])
    plants = list(dict.fromkeys(plant for _, plant in walked))
    assert len(plants) == len(scene.plants)  # one side of the row, every plant
    heights = np.array(first_line)[:, 2].reshape(len(plants), 3, per).mean(axis=2)  # each ellipse's centre
    for index, plant in enumerate(plants):
        bands = [scan_target(scene.plant(plant), band, 3)[2] for band in range(3)]
        assert np.allclose(heights[index], bands if index % 2 == 0 else bands[::-1], atol=1e-6)
    assert heights.min() < scan_target(scene.plants[0])[2] - 0.5 < scan_target(scene.plants[0])[2] + 0.5 < heights.max()
