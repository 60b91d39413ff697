"""Motion blur of the colour sensor's frames: the shutter's poses come from the flown state, Cycles blurs along the
motion (and not at rest), and the ideal frame's colour, depth and masks stay those of a still camera."""

from __future__ import annotations

import math
from bisect import bisect_left

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from renderloop.config import Config, SensorConfig, load_config
from renderloop.render.camera import Intrinsics
from renderloop.render.motion import (
    FlownStates,
    exposure_poses,
    exposure_time,
    frames_motion,
    stored,
)
from renderloop.render.srgb import decode_u8
from renderloop.robot.kinematics import (
    camera_pose,
    camera_rotation,
    homogeneous,
    look_at,
    rot_z,
)
from renderloop.scene import meshes

ARM = Config().robot.arm


def _state(t: float) -> tuple[np.ndarray, float, np.ndarray]:
    """A synthetic flight: 1.5 m/s along x while climbing, yaw turning at 0.3 rad/s, the joints moving at constant rates."""
    return np.array([1.5 * t, 0.2, 1.0 + 0.1 * t]), 0.1 + 0.3 * t, np.array([0.1 + t, -0.2 - 0.5 * t, 0.3 * t])


def _flight(times: np.ndarray) -> np.ndarray:
    rows = []
    for t in times:
        position, yaw, joints = _state(t)
        rows.append([t, *position, *Rotation.from_euler("z", yaw).as_quat(), *joints])
    return np.array(rows)


def _analytic_camera(t: float) -> np.ndarray:
    position, yaw, joints = _state(t)
    return camera_pose(position, rot_z(yaw), ARM, joints)


def test_the_shutter_poses_are_the_flown_state_interpolated_between_ticks():
    states = FlownStates.of_rows(_flight(np.arange(0.0, 0.1001, 0.01)))  # 100 Hz control ticks
    position, rotation, joints = states.at(0.0437)
    expected_position, yaw, expected_joints = _state(0.0437)
    assert np.allclose(position, expected_position, atol=1e-12) and np.allclose(joints, expected_joints, atol=1e-12)
    assert np.allclose(rotation, rot_z(yaw), atol=1e-12)  # slerp of a turn at a constant rate is exact
    # before the first tick and after the last the robot holds its state (at rest before, hovering after)
    assert np.allclose(states.at(-0.5)[0], _state(0.0)[0]) and np.allclose(states.at(7.0)[0], _state(0.1)[0])
    t, exposure = 0.05, 0.017  # centred on a tick, opening and closing between ticks
    shutter = exposure_poses(states, ARM, t, _analytic_camera(t), exposure)
    assert np.allclose(shutter[0], _analytic_camera(t - exposure / 2), atol=1e-12)
    assert np.allclose(shutter[1], _analytic_camera(t + exposure / 2), atol=1e-12)
    assert 0.01 < np.linalg.norm(shutter[1][:3, 3] - shutter[0][:3, 3]) < 0.05  # 1.5 m/s over 17 ms, and the arm


def test_the_motion_is_relative_to_the_frames_pose_and_still_at_rest():
    states = FlownStates.of_rows(_flight(np.arange(0.0, 0.1001, 0.01)))
    t, exposure = 0.05, 0.02
    offset = homogeneous(rot_z(1e-3), (2e-4, -1e-4, 3e-4))  # MuJoCo's camera site, off the kinematic chain by rounding
    pose = offset @ _analytic_camera(t)
    shutter = exposure_poses(states, ARM, t, pose, exposure)
    relative = np.linalg.inv(_analytic_camera(t)) @ _analytic_camera(t + exposure / 2)
    assert np.allclose(shutter[1], pose @ relative, atol=1e-12)
    at_rest = _flight(np.array([0.0]))[0, 1:]
    resting = FlownStates.of_rows([[0.01 * tick, *at_rest] for tick in range(5)])
    assert np.allclose(exposure_poses(resting, ARM, 0.02, pose, exposure), [pose, pose], atol=1e-12)


def test_the_online_cameras_window_of_the_log_gives_the_batch_renders_poses_to_the_bit():
    """The online camera interpolates in the ticks flown so far, from the last one before the shutter opens up to the
    first one at or after it closes; the batch render in the whole flight.csv. Same rounding, same poses."""
    times = np.round(np.arange(0.0, 2.0, 0.01), 6)
    full = np.array([stored(row) for row in _flight(times)])  # as flight.csv holds it
    settings = SensorConfig(enabled=True)
    for index, t in enumerate(times[::37]):
        exposure = exposure_time(settings, 7, index)
        pose = _analytic_camera(t)
        batch = exposure_poses(FlownStates.of_rows(full), ARM, t, pose, exposure)
        last = bisect_left(list(full[:, 0]), t + exposure / 2)  # the tick at which the online camera asks for it
        first = max(bisect_left(list(full[:, 0]), t - exposure / 2) - 1, 0)
        online = exposure_poses(FlownStates.of_rows(full[first:last + 1]), ARM, t, pose, exposure)
        assert np.array_equal(batch, online)
    drawn = [exposure_time(settings, 7, index) for index in range(50)]
    assert all(0.008 <= e <= 0.025 for e in drawn) and drawn == [exposure_time(settings, 7, i) for i in range(50)]
    assert exposure_time(settings.model_copy(update={"exposure_time": (0.01, 0.01)}), 7, 3) == 0.01
    poses = np.array([_analytic_camera(t) for t in times[:3]])
    batch = frames_motion(FlownStates.of_rows(full), ARM, times[:3], poses, settings, 7)
    assert np.array_equal(batch[2], exposure_poses(FlownStates.of_rows(full), ARM, times[2], poses[2], exposure_time(settings, 7, 2)))


# Cycles ---------------------------------------------------------------------------------------------------------


def _tiny_config(width: int = 64, height: int = 48, samples: int = 1):
    return load_config("demo").override({"camera": {"width": width, "height": height}, "renderer": {"samples": samples, "denoise": False}})


@pytest.fixture(scope="module")
def square():
    """A bright square 1 m in front of the camera on a dark wall, the camera looking along +x; 16 samples, so that
    one frame's edges are not lost in the noise of one (64x48 px, still a fraction of a second)."""
    from renderloop.render.cycles import CyclesRenderer

    config = _tiny_config(samples=16)
    intrinsics = Intrinsics.from_config(config.camera)
    objects = [("square", meshes.box(np.array([2.0, 0.0, 1.0]), (0.02, 0.5, 0.5)), (0.9, 0.9, 0.9), 1),
               ("wall", meshes.box(np.array([2.5, 0.0, 1.0]), (0.02, 8.0, 8.0)), (0.02, 0.02, 0.02), 0)]
    with CyclesRenderer.from_objects(objects, config, intrinsics) as renderer:
        pose = homogeneous(camera_rotation(0.0, 0.0), (1.0, 0.0, 1.0))
        rows, cols = np.nonzero(renderer.render(pose).mask == 1)
        yield renderer, pose, intrinsics, (rows.min(), rows.max(), cols.min(), cols.max())


def _spread(profile: np.ndarray) -> float:
    """Pixels the steepest step of `profile` (means along the edges) would take to rise its full height: about 1 for a
    sharp edge, the blur's length for an edge smeared over it (the square's shading slopes far less than either)."""
    return float((profile.max() - profile.min()) / np.abs(np.diff(profile)).max())


def _spreads(rgb: np.ndarray, box: tuple[int, int, int, int]) -> tuple[float, float]:
    """Spread of the square's edges along image x (the motion) and along image y (across it): each profile a mean
    over the square's inner rows or columns, within a margin of 12 px about it, in linear light (where blur adds)."""
    grey = decode_u8(rgb).mean(axis=2)
    top, bottom, left, right = box
    height, width = grey.shape
    rows, cols = slice(max(top - 12, 0), min(bottom + 13, height)), slice(max(left - 12, 0), min(right + 13, width))
    return _spread(grey[top + 3 : bottom - 2, cols].mean(axis=0)), _spread(grey[rows, left + 3 : right - 2].mean(axis=1))


def test_a_camera_moving_fast_sideways_blurs_the_sensor_frame_along_its_motion(square):
    renderer, pose, intrinsics, box = square
    ideal = renderer.render(pose).rgb
    sideways = 0.2  # m along optical x over the exposure: 0.2 * fx / 1 m ~ 12 px on the square 1 m away
    start, end = pose.copy(), pose.copy()
    start[:3, 3] -= pose[:3, 0] * sideways / 2
    end[:3, 3] += pose[:3, 0] * sideways / 2
    blurred = renderer.render_blurred(start, end)
    along, across = _spreads(blurred, box)
    sharp_along, sharp_across = _spreads(ideal, box)
    ramp = sideways * intrinsics.fx / 1.0  # px each vertical edge is smeared over
    assert sharp_along < 2.5 and sharp_across < 2.5
    assert 0.6 * ramp < along < 1.5 * ramp  # the square's left and right edges are ramps as long as the motion
    assert across < 2.5  # its top and bottom edges stay sharp
    assert abs(decode_u8(blurred).mean() / decode_u8(ideal).mean() - 1) < 0.05  # light spread, not lost


def test_a_camera_at_rest_gives_the_unblurred_frame_and_blurring_leaves_the_next_frame_alone(square):
    renderer, pose, _, box = square
    before = renderer.render(pose)
    still = renderer.render_blurred(pose, pose)
    assert np.abs(still.astype(float) - before.rgb).mean() < 2.0  # equal within the noise of the samples
    assert np.allclose(_spreads(still, box), _spreads(before.rgb, box), rtol=0.2)
    moved = pose.copy()
    moved[:3, 3] += pose[:3, 0] * 0.1
    renderer.render_blurred(pose, moved)
    after = renderer.render(pose)  # the still camera is back, to the bit
    assert np.array_equal(after.rgb, before.rgb) and np.array_equal(after.depth, before.depth)
    assert np.array_equal(after.mask, before.mask)


def test_the_sensor_being_on_leaves_the_ideal_colour_depth_and_masks_unchanged():
    from renderloop.render.executor import FrameWorker, blurs_motion
    from renderloop.rundir import names
    from renderloop.scene.generate import generate_scene

    config = _tiny_config(96, 72)
    scene = generate_scene(config)
    plant = scene.plants[0]
    target = np.array([plant.position[0], plant.position[1], plant.position[2] + 0.5])
    pose = look_at(target + np.array([-0.5, 0.05, 0.1]), target)
    moved = pose.copy()
    moved[:3, 3] += pose[:3, 0] * 0.05
    sensor = config.override({"camera": {"sensor": SensorConfig(enabled=True)}})
    assert blurs_motion(sensor) and not blurs_motion(sensor.override({"renderer": {"backend": "raster"}})) and not blurs_motion(config)
    worker = FrameWorker(sensor, scene)
    try:
        worker.render_pose(0, moved, np.array([pose, moved]))  # a blurred frame before, as in a worker's stream
        _, on, timings = worker.render_pose(1, pose, np.array([pose, moved]))
    finally:
        worker.close()
    worker = FrameWorker(config, scene)
    try:
        _, off, _ = worker.render_pose(1, pose)
    finally:
        worker.close()
    assert "motion_blur" in timings and names.RGB_SENSOR in on and names.RGB_SENSOR not in off
    for stream in (names.RGB, names.DEPTH, names.MASKS):
        assert on[stream] == off[stream], stream
    assert math.isfinite(timings["motion_blur"])


def test_the_shutter_poses_are_the_same_bits_wherever_the_flown_states_lie_in_memory():
    """The online camera interpolates a slice of the ticks flown so far, the batch render flight.csv's whole table:
    the same rows at another address must give the same poses, to the bit (BLAS's dot rounds by alignment)."""
    times = np.arange(0.0, 0.1001, 0.01)
    tumbling = Rotation.from_rotvec(np.outer(times, [3.0, -2.0, 5.0]) + [0.3, 0.2, 0.1]).as_quat()
    rows = np.array([stored(row) for row in np.column_stack([_flight(times)[:, :4], tumbling, _flight(times)[:, 8:]])])
    whole = FlownStates.of_rows(rows)  # quaternions off unit length by the six decimals flight.csv keeps
    for t in np.linspace(0.012, 0.088, 40):
        expected = exposure_poses(whole, ARM, t, _analytic_camera(t), 0.013)
        for offset in range(1, 8):
            buffer = np.zeros(offset + rows.size)
            buffer[offset:] = rows.ravel()
            moved = FlownStates.of_rows(buffer[offset:].reshape(rows.shape))
            assert np.array_equal(exposure_poses(moved, ARM, t, _analytic_camera(t), 0.013), expected), (t, offset)
