from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from renderloop.config import RobotConfig
from renderloop.robot.kinematics import (
    UnreachablePose,
    camera_pose,
    camera_pose_to_dofs,
    camera_rotation,
    dofs_to_camera_pose,
    homogeneous,
    look_at,
)
from renderloop.robot.mjcf import CAMERA_NAME, CAMERA_SITE, JOINT_NAMES
from renderloop.robot.rotors import GRAVITY, RotorModel
from renderloop.scene.world import world_xml


@pytest.fixture(scope="module")
def model(paper) -> mujoco.MjModel:
    config, scene = paper
    return mujoco.MjModel.from_xml_string(world_xml(scene, config))


def _set_state(model, data, position, quat_xyzw, q) -> None:
    data.qpos[:3] = position
    data.qpos[3:7] = np.roll(quat_xyzw, 1)  # MuJoCo stores w first
    data.qpos[7:10] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)


def test_world_has_one_free_joint_and_three_arm_hinges(model):
    types = list(model.jnt_type)
    assert types.count(mujoco.mjtJoint.mjJNT_FREE) == 1
    hinges = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, i) for i, t in enumerate(types) if t == mujoco.mjtJoint.mjJNT_HINGE]
    assert hinges == list(JOINT_NAMES)
    assert model.nu == 7 and model.nq == 10
    assert model.opt.timestep <= 0.002


def test_camera_site_matches_forward_kinematics(paper, model):
    config, _ = paper
    data = mujoco.MjData(model)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, CAMERA_SITE)
    camera = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA_NAME)
    rng = np.random.default_rng(1)
    low, high = config.robot.arm.joint_limits
    for _ in range(1000):
        position = rng.uniform(-5, 5, 3)
        attitude = Rotation.random(random_state=rng)
        q = rng.uniform(low, high, 3)
        _set_state(model, data, position, attitude.as_quat(), q)
        expected = camera_pose(position, attitude.as_matrix(), config.robot.arm, q)
        assert np.abs(data.site_xpos[site] - expected[:3, 3]).max() < 1e-9
        assert np.abs(data.site_xmat[site].reshape(3, 3) - expected[:3, :3]).max() < 1e-9
        # MuJoCo's own camera (looking down -z, y up) is the optical frame turned about x.
        assert np.allclose(data.cam_xmat[camera].reshape(3, 3), expected[:3, :3] @ np.diag([1, -1, -1]), atol=1e-9)


def test_optical_frame_conventions(paper):
    config, _ = paper
    pose = dofs_to_camera_pose([0, 0, 1, 0, 0, 0, 0], config.robot.arm)
    # Level arm, yaw 0: the camera looks along world +x, image x is world -y (right), image y is world -z (down).
    assert np.allclose(pose[:3, 2], [1, 0, 0]) and np.allclose(pose[:3, 0], [0, -1, 0]) and np.allclose(pose[:3, 1], [0, 0, -1])
    reach = sum(config.robot.arm.link_lengths) + config.robot.arm.mount[0]
    assert np.allclose(pose[:3, 3], [reach, 0, 1 + config.robot.arm.mount[2]])
    down = dofs_to_camera_pose([0, 0, 1, 0, 0, 0, 0.3], config.robot.arm)
    assert down[2, 2] == pytest.approx(-math.sin(0.3))  # positive joint angle pitches the camera down


def test_inverse_kinematics_round_trip(paper):
    arm = paper[0].robot.arm
    rng = np.random.default_rng(2)
    for _ in range(500):
        yaw, pitch = rng.uniform(-math.pi, math.pi), rng.uniform(-0.7, 0.7)
        posture = rng.uniform(-0.4, 0.4, 2)  # q3 stays within the +-1.6 rad limits
        wanted = homogeneous(camera_rotation(yaw, pitch), rng.uniform(-4, 4, 3))
        dofs = camera_pose_to_dofs(wanted, arm, posture)
        assert np.allclose(dofs[4:6], posture)
        assert np.abs(dofs_to_camera_pose(dofs, arm) - wanted).max() < 1e-12


def test_look_at_points_the_optical_axis_at_the_target(paper):
    arm = paper[0].robot.arm
    target = np.array([3.0, 2.5, 1.0])
    pose = look_at([2.2, 2.0, 1.3], target)
    direction = (target - pose[:3, 3]) / np.linalg.norm(target - pose[:3, 3])
    assert np.allclose(pose[:3, 2], direction)
    assert abs(pose[2, 0]) < 1e-12  # image x stays horizontal: no roll
    assert np.allclose(dofs_to_camera_pose(camera_pose_to_dofs(pose, arm), arm), pose)


def test_unreachable_camera_poses_are_refused(paper):
    arm = paper[0].robot.arm
    rolled = homogeneous(camera_rotation(0.2, 0.1) @ Rotation.from_euler("z", 0.3).as_matrix(), [0, 0, 1])
    with pytest.raises(UnreachablePose, match="roll"):
        camera_pose_to_dofs(rolled, arm)
    with pytest.raises(UnreachablePose, match="q3"):
        camera_pose_to_dofs(homogeneous(camera_rotation(0.0, 1.5), [0, 0, 1]), arm, posture=(-1.0, -1.0))


def test_mixer_round_trip_and_saturation():
    rotors = RotorModel(RobotConfig())
    rng = np.random.default_rng(3)
    assert np.allclose(rotors.K @ rotors.K_inv, np.eye(4))
    for _ in range(200):
        speeds = rng.uniform(200, rotors.max_speed, 4)
        wrench = rotors.wrench(speeds)
        mixed, saturated = rotors.mix(wrench)
        assert np.allclose(mixed, speeds) and not saturated
    too_much = rotors.wrench(np.full(4, rotors.max_speed)) * 1.5
    clamped, saturated = rotors.mix(too_much)
    assert saturated and np.all(clamped <= rotors.max_speed)
    stopped, saturated = rotors.mix(np.array([0.0, 50.0, 0.0, 0.0]))  # a negative w² stops that rotor
    assert saturated and np.all(stopped >= 0.0)


def test_hover_speed_for_the_total_mass_and_mujoco_actuators(paper, model):
    config, _ = paper
    rotors = RotorModel(config.robot)
    total_mass = model.body_subtreemass[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "uav")]
    assert total_mass == pytest.approx(config.robot.mass + sum(config.robot.arm.link_masses))
    hover = rotors.hover_speed(total_mass)
    assert hover == pytest.approx(math.sqrt(total_mass * GRAVITY / (4 * config.robot.rotor.kf)))
    assert rotors.wrench(np.full(4, hover))[0] == pytest.approx(total_mass * GRAVITY)
    assert 0.5 * rotors.max_speed < hover < rotors.max_speed

    data = mujoco.MjData(model)
    rng = np.random.default_rng(4)
    for _ in range(20):  # MuJoCo's actuators apply exactly the wrench of our input mapping
        wanted = np.array([total_mass * GRAVITY, *rng.uniform(-1, 1, 2), rng.uniform(-0.1, 0.1)])
        data.qpos[:] = 0
        data.qpos[3] = 1
        data.ctrl[:4] = rotors.mix(wanted)[0] ** 2
        mujoco.mj_forward(model, data)
        assert np.allclose(data.qfrc_actuator[2:6], wanted, atol=1e-9)
        assert np.allclose(data.qfrc_actuator[:2], 0, atol=1e-12)


def test_motor_lag_is_first_order():
    rotors = RotorModel(RobotConfig.model_validate({"rotor": {"time_constant": 0.05}}))
    speed, dt = np.zeros(4), 0.001
    for _ in range(50):
        speed = rotors.lag(speed, np.full(4, 1000.0), dt)
    assert speed[0] == pytest.approx(1000 * (1 - math.exp(-1)), rel=1e-9)
    instant = RotorModel(RobotConfig())
    assert np.allclose(instant.lag(np.zeros(4), np.full(4, 7.0), dt), 7.0)
