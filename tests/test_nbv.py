"""Next-best views: the voxel map built from depth frames only, checked against analytic geometry (a plane, boxes and
a sphere ray-cast here in numpy), and the views chosen from it: they see what the map does not know, they are
reachable and clear in MuJoCo, and the same inputs choose the same views."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import scene_for

from renderloop.errors import UserError
from renderloop.loop.nbv import Candidate, candidate_views, canopy_box, choose_views, flight_time, select
from renderloop.loop.viewpoints import Projector, View, camera_position, view_at
from renderloop.loop.voxels import FREE, OCCUPIED, UNKNOWN, VoxelMap
from renderloop.planning.waypoints import scan_target
from renderloop.render.camera import Intrinsics
from renderloop.robot.kinematics import camera_pose_to_dofs, dofs_to_camera_pose, look_at
from renderloop.scene.world import world_xml

FRUIT_RADIUS = 0.035  # m
FIRST_PASS = [View(math.radians(azimuth), height, 0.55) for azimuth in (-20, 0, 20) for height in (-0.2, 0.0, 0.2)]
WALL = (np.array([0.0, 0.0, 0.0]), np.array([0.02, 4.0, 3.0]))  # behind the demo row, seen from its +x side


def tiny_camera(hfov_deg: float) -> Intrinsics:
    fx = 64 / (2 * math.tan(math.radians(hfov_deg) / 2))
    return Intrinsics(64, 48, fx, fx, 31.5, 23.5)


def ray_cast(pose: np.ndarray, intrinsics: Intrinsics, boxes: list, spheres: list) -> np.ndarray:
    """Planar depth (0: no return) of axis-aligned boxes (lower, upper) and spheres (centre, radius), every pixel."""
    v, u = np.mgrid[0:intrinsics.height, 0:intrinsics.width]
    rays = np.stack([(u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy, np.ones(u.shape)], -1)
    directions = rays.reshape(-1, 3) @ pose[:3, :3].T  # t along these is planar depth
    origin = pose[:3, 3]
    depth = np.full(len(directions), np.inf)
    for lower, upper in boxes:
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (lower - origin) / directions, (upper - origin) / directions
        near, far = np.nanmax(np.minimum(ta, tb), axis=1), np.nanmin(np.maximum(ta, tb), axis=1)
        depth = np.where((near <= far) & (near > 0), np.minimum(depth, near), depth)
    for centre, radius in spheres:
        offset = origin - centre
        a, b, c = (directions**2).sum(1), directions @ offset, offset @ offset - radius**2
        disc = b * b - a * c
        t = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
        depth = np.where((disc >= 0) & (t > 0), np.minimum(depth, t), depth)
    return np.where(np.isfinite(depth), depth, 0.0).reshape(intrinsics.height, intrinsics.width).astype(np.float32)


def blocked(start: np.ndarray, end: np.ndarray, boxes: list) -> bool:
    """Whether the segment start-end passes through one of the boxes."""
    direction = end - start
    for lower, upper in boxes:
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (lower - start) / direction, (upper - start) / direction
        near, far = np.nanmax(np.minimum(ta, tb)), np.nanmin(np.maximum(ta, tb))
        if near <= far and far > 0 and near < 1:
            return True
    return False


def in_image(pose: np.ndarray, intrinsics: Intrinsics, point: np.ndarray) -> bool:
    optical = pose[:3, :3].T @ (point - pose[:3, 3])
    u, v = intrinsics.project(optical)[0]
    return bool(optical[2] > 0 and -0.5 <= u <= intrinsics.width - 0.5 and -0.5 <= v <= intrinsics.height - 0.5)


@pytest.fixture(scope="module")
def greenhouse(tmp_path_factory):
    """The demo greenhouse, its world.xml, and its first plant (at the end of the row: its -y side is open)."""
    config, scene = scene_for("demo", 0)
    world = tmp_path_factory.mktemp("nbv") / "world.xml"
    world.write_text(world_xml(scene, config), encoding="utf-8")
    return config, scene, world, scene.plants[0]


@pytest.fixture(scope="module")
def hidden_fruit(greenhouse):
    """A fruit in the middle of the plant behind a leaf (a plate 5 cm towards +x), and a map of the first pass: nine
    depth frames from the plant's +x side, which the leaf hides the fruit from."""
    config, _, _, plant = greenhouse
    target = scan_target(plant)
    leaf = (target + [0.05, -0.1, -0.1], target + [0.06, 0.1, 0.1])
    intrinsics = tiny_camera(config.camera.hfov_deg)
    lower, upper = canopy_box(plant)
    voxels = VoxelMap(lower - 0.15, upper + 0.15)
    poses = [look_at(camera_position(plant, view), target) for view in FIRST_PASS]
    for pose in poses:
        voxels.integrate(ray_cast(pose, intrinsics, [leaf, WALL], [(target, FRUIT_RADIUS)]), pose, intrinsics, stride=1)
    return target, leaf, intrinsics, voxels, poses


# ------------------------------------------------------------------------------------------------ the voxel map


def test_a_plane_seen_head_on_is_occupied_at_its_distance_free_before_it_and_unknown_behind_it():
    intrinsics = tiny_camera(57.0)
    voxels = VoxelMap((-0.3, -0.3, -0.3), (0.3, 0.3, 0.3), 0.02)
    pose = look_at((-1.0, 0.0, 0.0), (0.0, 0.0, 0.0))  # optical z along world +x
    voxels.integrate(np.full((48, 64), 1.01, np.float32), pose, intrinsics, stride=1)  # the plane x = 0.01
    assert voxels.shape == (30, 30, 30)
    on_plane = voxels.state[15]  # x from 0.00 to 0.02
    assert (on_plane == OCCUPIED).all()  # the frustum is wider than the box at 1 m
    assert (voxels.state[:15] == FREE).all() and (voxels.state[16:] == UNKNOWN).all()
    assert voxels.unknown_fraction((-0.3, -0.3, -0.3), (0.0, 0.3, 0.3)) == 0.0
    assert voxels.unknown_fraction((0.02, -0.3, -0.3), (0.3, 0.3, 0.3)) == 1.0
    assert voxels.unknown_fraction((-0.3, -0.3, -0.3), (0.3, 0.3, 0.3)) == pytest.approx(14 / 30)
    assert voxels.state_at(np.array([[0.01, 0.2, -0.2], [-0.1, 0.0, 0.0], [0.1, 0.0, 0.0], [5.0, 0.0, 0.0]])).tolist() == [
        OCCUPIED, FREE, UNKNOWN, UNKNOWN]


def test_the_returns_of_an_oblique_frame_land_in_occupied_voxels_and_the_space_before_them_is_free():
    intrinsics = tiny_camera(57.0)
    voxels = VoxelMap((-0.3, -0.3, 0.0), (0.3, 0.3, 0.6), 0.02)
    block = (np.array([-0.105, -0.153, 0.0]), np.array([0.123, 0.207, 0.311]))  # on the map's floor, faces off the grid
    pose = look_at((0.7, -0.4, 0.8), (0.0, 0.0, 0.2))
    depth = ray_cast(pose, intrinsics, [block], [])
    voxels.integrate(depth, pose, intrinsics, stride=1)
    v, u = np.nonzero(depth > 0)
    optical = intrinsics.back_project(np.column_stack([u, v]), depth[v, u].astype(float))
    points = optical @ pose[:3, :3].T + pose[:3, 3]
    inside = ((points > voxels.lower) & (points < voxels.upper)).all(axis=1)
    assert inside.sum() > 500
    assert (voxels.state_at(points[inside]) == OCCUPIED).all()
    rays = points[inside] - pose[:3, 3]
    before = points[inside] - 0.1 * rays / np.linalg.norm(rays, axis=1, keepdims=True)  # 10 cm back along the ray
    clearance = np.linalg.norm(np.maximum(np.maximum(block[0] - before, before - block[1]), 0.0), axis=1)
    before = before[(clearance > 0.035) & ((before > voxels.lower) & (before < voxels.upper)).all(axis=1)]
    assert len(before) > 200 and (voxels.state_at(before) == FREE).all()  # off the voxels the surface touches
    assert voxels.state_at([[0.0, 0.0, 0.1]])[0] == UNKNOWN  # inside the box


def test_no_return_marks_nothing_and_a_return_beyond_max_range_marks_the_ray_free_up_to_it():
    intrinsics = tiny_camera(57.0)
    pose = look_at((-1.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    nothing = VoxelMap((-0.3, -0.3, -0.3), (0.3, 0.3, 0.3))
    depth = np.zeros((48, 64), np.float32)
    depth[:24] = np.nan
    nothing.integrate(depth, pose, intrinsics, stride=1)
    assert (nothing.state == UNKNOWN).all()
    far = VoxelMap((-0.3, -0.3, -0.3), (0.3, 0.3, 0.3))
    far.integrate(np.full((48, 64), 1.01, np.float32), pose, intrinsics, stride=1, max_range=1.0)
    assert not (far.state == OCCUPIED).any()
    assert (far.state_at([[-0.05, 0.0, 0.0], [0.03, 0.0, 0.0]]) == [FREE, UNKNOWN]).all()


def test_a_point_is_visible_in_the_image_and_range_unless_an_occupied_voxel_stands_between():
    intrinsics = tiny_camera(57.0)
    voxels = VoxelMap((-0.3, -0.3, -0.3), (0.3, 0.3, 0.3))
    pose = look_at((-1.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    depth = np.zeros((48, 64), np.float32)
    depth[20:28, 28:36] = 1.01  # a small patch of the plane x = 0.01 round the optical axis
    voxels.integrate(depth, pose, intrinsics, stride=1)
    points = np.array([
        [0.01, 0.0, 0.0],  # on the patch: its own voxel does not hide it
        [0.03, 0.0, 0.0],  # in the next voxel, on the surface too
        [0.2, 0.0, 0.0],  # behind the patch
        [0.2, 0.25, 0.0],  # behind the plane but beside the patch: unknown space hides nothing
        [-0.2, 0.0, 0.0],  # in front
        [-0.2, 0.0, 0.8],  # outside the image
        [-2.0, 0.0, 0.0],  # behind the camera
    ])
    assert voxels.visible(pose, intrinsics, points).tolist() == [True, True, False, True, True, False, False]
    assert voxels.visible(pose, intrinsics, points[4:5], max_range=0.5).tolist() == [False]


def test_the_gain_counts_distinct_unknown_voxels_up_to_the_first_occupied_one():
    fine = Intrinsics(128, 96, 117.8, 117.8, 63.5, 47.5)  # 57°: under 1.2 cm between rays at 1.3 m, every voxel met
    voxels = VoxelMap((-0.3, -0.3, -0.3), (0.3, 0.3, 0.3))
    front = look_at((-1.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    core = ((-0.3, -0.2, -0.2), (0.3, 0.2, 0.2))  # the part of the box inside the image from the front and the back
    assert voxels.gain(front, fine, *core, stride=1) == 30 * 20 * 20
    voxels.integrate(np.full((96, 128), 1.01, np.float32), front, fine, stride=1)  # the plane x = 0.01
    assert voxels.gain(front, fine, voxels.lower, voxels.upper, stride=1) == 0  # free up to the plane, which hides the rest
    back = look_at((1.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    seen = voxels.seen_unknown(back, fine, *core, stride=1)
    assert len(seen) == len(np.unique(seen)) == 14 * 20 * 20  # the unknown half, up to the plane
    assert (voxels.state.reshape(-1)[seen] == UNKNOWN).all()
    assert voxels.gain(back, fine, (0.1, -0.2, -0.2), (0.3, 0.2, 0.2), stride=1) == 10 * 20 * 20
    assert 0 < voxels.gain(back, fine, *core, stride=1, max_range=0.95) < 14 * 20 * 20


def test_wrong_arguments_are_one_line_user_errors():
    voxels = VoxelMap((0, 0, 0), (0.1, 0.1, 0.1))
    intrinsics = tiny_camera(57.0)
    pose = look_at((-1.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    cases = [
        (lambda: VoxelMap((0, 0, 0), (1, 1, 1), -0.02), "voxel"),
        (lambda: VoxelMap((0, 0, 0), (1, 0, 1)), "empty box"),
        (lambda: VoxelMap((0, 0, 0), (100, 100, 100), 0.001), "more than"),
        (lambda: voxels.integrate(np.zeros((4, 4)), pose, intrinsics), "depth"),
        (lambda: voxels.integrate(np.zeros((48, 64)), pose, intrinsics, stride=0), "stride"),
        (lambda: voxels.integrate(np.zeros((48, 64)), np.eye(3), intrinsics), "pose"),
        (lambda: voxels.gain(pose, intrinsics, (1, 1, 1), (2, 2, 2)), "outside the voxel map"),
        (lambda: voxels.visible(pose, intrinsics, np.zeros((1, 3)), max_range=-1.0), "max_range"),
        (lambda: select([], voxels, intrinsics, (voxels.lower, voxels.upper), np.zeros((0, 3)), start=None,
                        velocity_limits=(1.5, 1.5, 0.5, 0.3), budget_s=10.0, max_views=0, min_gain=20), "max_views"),
        (lambda: select([], voxels, intrinsics, (voxels.lower, voxels.upper), np.zeros(4), start=None,
                        velocity_limits=(1.5, 1.5, 0.5, 0.3), budget_s=10.0, max_views=1, min_gain=20), "weak"),
    ]
    for call, words in cases:
        with pytest.raises(UserError, match=words) as error:
            call()
        assert "\n" not in str(error.value)


# ------------------------------------------------------------------------------------------------ next-best views


def test_a_fruit_hidden_behind_a_leaf_is_seen_by_the_first_chosen_view(greenhouse, hidden_fruit):
    config, scene, world, plant = greenhouse
    target, leaf, intrinsics, voxels, poses = hidden_fruit
    for pose in poses:  # the first pass did not see it, by the map and by the geometry
        assert blocked(pose[:3, 3], target, [leaf])
    assert not any(voxels.visible(pose, intrinsics, target[None])[0] for pose in poses)
    projector = Projector(config, scene, plant, world)
    views, reason = choose_views(projector, voxels, intrinsics, plant, weak=target[None], budget_s=60.0, max_views=1,
                                 min_gain=20, start=poses[4][:3, 3], planner=config.planner, stride=2)
    assert len(views) == 1, reason
    first = views[0]
    assert first.gain_fruit == 1 and first.gain_cells >= 20
    assert in_image(first.pose, intrinsics, target) and not blocked(first.pose[:3, 3], target, [leaf])
    start = view_at(plant, poses[4][:3, 3])
    assert first.flight_s == pytest.approx(flight_time(start, first.view, config.planner.velocity_limits))


def test_chosen_views_are_reachable_and_clear_of_the_greenhouse_and_flown_in_a_short_order(greenhouse, hidden_fruit):
    config, scene, world, plant = greenhouse
    target, _, intrinsics, voxels, poses = hidden_fruit
    projector = Projector(config, scene, plant, world)
    start = poses[4][:3, 3]
    views, _ = choose_views(projector, voxels, intrinsics, plant, weak=target[None], budget_s=60.0, max_views=4,
                            min_gain=20, start=start, planner=config.planner, stride=2)
    assert len(views) >= 2
    checker = Projector(config, scene, plant, world)  # a fresh MuJoCo model
    for view in views:
        dofs = checker.dofs(view.view)
        assert dofs is not None and np.allclose(dofs, view.dofs) and checker.clear(view.dofs[None])
        assert np.allclose(dofs_to_camera_pose(view.dofs, config.robot.arm), view.pose)
        assert np.allclose(view.pose[:3, 3], camera_position(plant, view.view))
    limits = config.planner.velocity_limits
    here, elapsed = view_at(plant, start), 0.0
    for k, view in enumerate(views):
        elapsed += flight_time(here, view.view, limits)
        assert view.flight_s == pytest.approx(elapsed) and view.flight_s <= 60.0
        later = [other.view for other in views[k:]]
        assert flight_time(here, view.view, limits) == pytest.approx(min(flight_time(here, v, limits) for v in later))
        here = view.view
    assert sum(view.gain_fruit for view in views) == 1


def test_the_same_inputs_choose_the_same_views(greenhouse, hidden_fruit):
    config, scene, world, plant = greenhouse
    target, _, intrinsics, voxels, poses = hidden_fruit
    runs = []
    for _ in range(2):
        projector = Projector(config, scene, plant, world)
        views, reason = choose_views(projector, voxels.copy(), intrinsics, plant, weak=target[None], budget_s=30.0,
                                     max_views=3, min_gain=20, start=poses[4][:3, 3], planner=config.planner, stride=2)
        runs.append(([(v.view, v.dofs.tobytes(), v.pose.tobytes(), v.gain_cells, v.gain_fruit, v.flight_s) for v in views],
                     reason))
    assert runs[0] == runs[1] and runs[0][0]


def test_no_budget_or_no_reachable_view_gives_no_views_and_a_reason(greenhouse, hidden_fruit):
    config, scene, world, plant = greenhouse
    target, _, intrinsics, voxels, poses = hidden_fruit
    projector = Projector(config, scene, plant, world)
    arguments = dict(weak=target[None], max_views=3, min_gain=20, start=poses[4][:3, 3], planner=config.planner)
    assert choose_views(projector, voxels, intrinsics, plant, budget_s=0.0, **arguments) == ([], "no flight time budget left")
    views, reason = select([], voxels, intrinsics, canopy_box(plant), target[None], start=None, budget_s=10.0,
                           velocity_limits=config.planner.velocity_limits, max_views=3, min_gain=20)
    assert views == [] and "no candidate view" in reason
    with pytest.raises(UserError, match="plant 1"):
        choose_views(projector, voxels, intrinsics, scene.plants[1], budget_s=10.0, **arguments)


def plain_candidates(config, plant, views: list[View]) -> list[Candidate]:
    """Candidates built from views alone, without MuJoCo: look_at poses and their inverse kinematics."""
    candidates = []
    for view in views:
        pose = look_at(camera_position(plant, view), scan_target(plant))
        candidates.append(Candidate(view, camera_pose_to_dofs(pose, config.robot.arm), pose))
    return candidates


def test_an_uncertain_fruit_outweighs_more_unknown_space(greenhouse):
    """Without MuJoCo: of a view that sees more unknown space and one that sees the fruit the count is unsure of, the
    rule picks the fruit; with no uncertain fruit, the space."""
    config, _, _, plant = greenhouse
    target = scan_target(plant)
    leaf = (target + [0.05, -0.1, -0.1], target + [0.06, 0.1, 0.1])
    intrinsics = tiny_camera(config.camera.hfov_deg)
    lower, upper = canopy_box(plant)
    voxels = VoxelMap(lower - 0.15, upper + 0.15)
    pose = look_at(camera_position(plant, View(0.0, 0.0, 0.55)), target)
    voxels.integrate(ray_cast(pose, intrinsics, [leaf, WALL], [(target, FRUIT_RADIUS)]), pose, intrinsics, stride=1)
    space, fruit = plain_candidates(config, plant, [View(math.radians(-60), 0.2, 0.65), View(math.radians(-100), 0.0, 0.35)])
    assert voxels.gain(space.pose, intrinsics, lower, upper, 2) > voxels.gain(fruit.pose, intrinsics, lower, upper, 2)
    assert blocked(space.pose[:3, 3], target, [leaf]) and not voxels.visible(space.pose, intrinsics, target[None])[0]
    assert not blocked(fruit.pose[:3, 3], target, [leaf]) and voxels.visible(fruit.pose, intrinsics, target[None])[0]
    arguments = dict(start=None, velocity_limits=config.planner.velocity_limits, budget_s=60.0, max_views=1,
                     min_gain=20, stride=2)
    chosen, _ = select([space, fruit], voxels, intrinsics, (lower, upper), target[None], **arguments)
    assert [view.view for view in chosen] == [fruit.view] and chosen[0].gain_fruit == 1
    chosen, _ = select([space, fruit], voxels, intrinsics, (lower, upper), np.zeros((0, 3)), **arguments)
    assert [view.view for view in chosen] == [space.view]


def test_what_a_chosen_view_sees_no_longer_counts_and_the_budget_passes_over_views_it_cannot_afford(greenhouse):
    config, _, _, plant = greenhouse
    intrinsics = tiny_camera(config.camera.hfov_deg)
    lower, upper = canopy_box(plant)
    voxels = VoxelMap(lower - 0.15, upper + 0.15)  # nothing seen yet
    near, again, far = plain_candidates(config, plant, [View(0.3, 0.0, 0.55), View(0.3, 0.0, 0.55), View(math.pi, 0.0, 0.55)])
    limits = config.planner.velocity_limits
    arguments = dict(start=View(0.0, 0.0, 0.55), velocity_limits=limits, min_gain=20, stride=2)
    chosen, reason = select([near, again], voxels, intrinsics, (lower, upper), np.zeros((0, 3)), budget_s=60.0,
                            max_views=2, **arguments)
    assert [view.view for view in chosen] == [near.view] and "too little" in reason  # the second sees nothing new
    assert chosen[0].gain_cells == voxels.gain(near.pose, intrinsics, lower, upper, 2)
    half_turn = flight_time(near.view, far.view, limits)
    assert half_turn > 5.0  # the yaw rate governs
    chosen, reason = select([far, near], voxels, intrinsics, (lower, upper), np.zeros((0, 3)),
                            budget_s=flight_time(View(0.0, 0.0, 0.55), near.view, limits) + 1.0, max_views=2, **arguments)
    assert [view.view for view in chosen] == [near.view] and "budget" in reason
    chosen, _ = select([far, near], voxels, intrinsics, (lower, upper), np.zeros((0, 3)), budget_s=60.0, max_views=2,
                       **arguments)
    assert [view.view for view in chosen] == [near.view, far.view]  # flown nearest first, whatever the choice's order
    assert chosen[1].flight_s == pytest.approx(chosen[0].flight_s + half_turn)


def test_a_view_and_its_camera_position_round_trip(greenhouse):
    _, _, _, plant = greenhouse
    for view in (View(0.3, -0.1, 0.5), View(math.pi, 0.2, 0.7), View(-2.0, 0.0, 0.35)):
        back = view_at(plant, camera_position(plant, view))
        assert np.allclose(back.array(), view.array())


def test_the_candidates_of_a_plant_in_a_row_leave_out_the_views_into_its_neighbours(greenhouse):
    config, scene, world, _ = greenhouse
    inner = scene.plants[1]  # neighbours at ±y
    candidates = candidate_views(Projector(config, scene, inner, world))
    azimuths = {round(math.degrees(c.view.azimuth)) for c in candidates}
    assert {0, 180} <= azimuths and not {80, 100, -80, -100} & azimuths


def test_views_of_a_tall_canopy_reach_up_it_and_look_near_their_own_height_while_a_short_one_keeps_three(tmp_path, greenhouse):
    from renderloop.config import load_config
    from renderloop.loop.nbv import heights
    from renderloop.loop.viewpoints import aim_point
    from renderloop.scene.generate import generate_scene

    _, _, _, short = greenhouse
    assert heights(short) == (-0.2, 0.0, 0.2)
    assert np.allclose(aim_point(short, camera_position(short, View(0.0, 0.2, 0.5))), scan_target(short))
    config = load_config("greenhouse").override({"plants": {"pepper_style": {"leaves": [20, 30]}}})
    scene = generate_scene(config)
    world = tmp_path / "world.xml"
    world.write_text(world_xml(scene, config), encoding="utf-8")
    plant = scene.plants[2]
    low, high = canopy_box(plant)[0][2], canopy_box(plant)[1][2]
    tall = heights(plant)
    assert len(tall) > 3 and np.all(np.diff(tall) <= 0.2 + 1e-9)
    middle = scan_target(plant)[2]
    assert middle + tall[0] < low + 0.5 and middle + tall[-1] > high - 0.5  # from near the bottom to near the top
    projector = Projector(config, scene, plant, world)
    for height in tall:
        view = View(math.pi, height, 0.55)  # from the aisle at -x
        position = camera_position(plant, view)
        aim = aim_point(plant, position)
        assert low < aim[2] < high and abs(aim[2] - position[2]) <= 0.3 + 1e-9
        assert projector.dofs(view) is not None  # the arm aims the camera there
