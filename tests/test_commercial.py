"""The commercial compartment: one line's scan from the path beside it, and renderers that build what the camera sees."""

from __future__ import annotations

import hashlib

import mujoco
import numpy as np
import pytest

from renderloop.config import load_config
from renderloop.errors import UserError
from renderloop.planning.scan import plan_scan
from renderloop.planning.waypoints import footprint_radius, plan_waypoints
from renderloop.robot.kinematics import dofs_to_camera_pose
from renderloop.scene.generate import generate_scene
from renderloop.scene.visible import visible_scene
from renderloop.scene.world import world_xml
from tests.conftest import scene_for

# sha256 of the demo's (seed 0) and the paper's (seed 7) scan waypoints, kind, plant, side and q* to 6 decimals, as
# planned before `planner.row` and `planner.sides` existed: their defaults plan the same waypoints
PLANS = {("demo", 0): "89654c2ca24eb5ac699b77c89c044effe074a8b13990617c712ad0088b7ba3a5",
         ("paper", 7): "72d5ed4ad13dcbae95070a359de1257d803cec7ad55d0ee260f354f00bec7f82"}


@pytest.fixture(scope="module")
def commercial():
    return scene_for("commercial", 0)


@pytest.fixture(scope="module")
def scan(commercial):
    """The mission of line 1, the inner line of the west double row, from the middle path."""
    config, scene = commercial
    return [w for w in plan_waypoints(scene, config.override({"planner": {"row": 1}})) if w.kind == "scan"]


@pytest.fixture(scope="module")
def view():
    """The compartment with 6 plant prototypes instead of 24, and the camera pose halfway along line 1's scan: what a
    renderer builds for a view does not depend on how many prototypes there are, and the builds take a third of the
    time."""
    config = load_config("commercial", seed=0).override({"plants": {"prototypes": 6}})
    scene = generate_scene(config)
    scan = [w for w in plan_waypoints(scene, config.override({"planner": {"row": 1}})) if w.kind == "scan"]
    return config, scene, dofs_to_camera_pose(scan[len(scan) // 2].dofs, config.robot.arm)


def _digest(waypoints) -> str:
    text = "\n".join(f"{w.kind},{w.plant},{w.side}," + ",".join(f"{v:.6f}" for v in w.dofs) for w in waypoints)
    return hashlib.sha256(text.encode()).hexdigest()


@pytest.mark.parametrize("preset, seed", sorted(PLANS))
def test_the_default_planner_plans_the_demo_and_paper_scans_as_before(preset, seed):
    config, scene = scene_for(preset, seed)
    assert _digest(plan_waypoints(scene, config)) == PLANS[(preset, seed)]


def test_a_mission_of_the_commercial_preset_scans_every_plant_of_its_line_from_the_path_beside_it(commercial, scan):
    config, scene = commercial
    line = scene.rows[1]
    assert config.mission.split == "rows" and config.planner.row is None  # the compartment, a mission a line
    assert {w.plant for w in scan} == set(line.plants)
    assert {w.side for w in scan} == {"right"}  # the path to +x; its double row's other line stands 0.4 m to -x
    per_plant = config.planner.bands * config.planner.points_per_ellipse
    assert len(scan) == per_plant * len(line.plants)
    bodies = np.array([w.dofs[0] for w in scan])
    other = scene.rows[2].table
    # in the path, the body as far from the next line's gutter as the footprint asks, the camera 0.44 m off the axis
    assert np.all(bodies <= other.center[0] - other.size[0] / 2 - footprint_radius(config))
    cameras = np.array([dofs_to_camera_pose(w.dofs, config.robot.arm)[0, 3] for w in scan]) - line.table.center[0]
    assert np.allclose(cameras, 0.44, atol=0.01)


def test_the_commercial_scan_is_checked_clear_of_the_crop_and_its_structure(commercial):
    config, scene = commercial
    plan = plan_scan(scene, config, mujoco.MjModel.from_xml_string(world_xml(scene, config)))
    assert plan.trajectory.waypoint_times[-1] > 0


def test_every_line_of_the_compartment_can_be_scanned_from_its_aisle(commercial):
    config, scene = commercial
    for row in scene.rows:
        scan = [w for w in plan_waypoints(scene, config.override({"planner": {"row": row.id}})) if w.kind == "scan"]
        assert {w.plant for w in scan} == set(row.plants) and len({w.side for w in scan}) == 1


def test_a_row_without_an_aisle_and_a_row_the_greenhouse_lacks_are_refused(commercial):
    config, scene = commercial
    # 2 m from its axis, the line's scan would stand in the next line's gutter on one side and past the wall on the other
    with pytest.raises(UserError, match=r"planner.distance: scan waypoints of plant \d+ come within 0.64 m"):
        plan_waypoints(scene, config.override({"planner": {"distance": 2.0}}))
    with pytest.raises(UserError, match=r"planner.row: the greenhouse has 4 rows \(0 to 3\), not 4"):
        config.override({"planner": {"row": 4}})
    with pytest.raises(UserError, match=r"planner.distance: scan waypoints of plant \d+ come within"):
        plan_waypoints(scene, config.override({"planner": {"sides": "both"}}))


def test_culling_keeps_the_plants_near_the_camera_and_the_truth_whole(view):
    config, scene, pose = view
    seen = visible_scene(scene, pose[None, :3, 3], config.camera.clip[1])
    assert 0 < len(seen.plants) < len(scene.plants) and 0 < len(seen.environment.plants) < len(scene.environment.plants)
    far = config.camera.clip[1]
    for plant in scene.plants:  # every plant whose base is within the far clip is built, none farther than its box
        distance = np.linalg.norm(np.asarray(plant.position) - pose[:3, 3])
        if distance <= far:
            assert plant in seen.plants
        if plant in seen.plants:
            assert distance <= far + 4.0
    assert {p.id for p in seen.peppers} == {p.id for p in scene.peppers if p.plant in {q.id for q in seen.plants}}
    assert visible_scene(scene, None, far) is scene and len(scene.plants) == 208


def test_a_culled_raster_frame_equals_the_whole_scenes_frame_with_fewer_geoms(view):
    from renderloop.render.camera import Intrinsics
    from renderloop.render.raster import HIDDEN, RasterRenderer

    config, scene, pose = view
    config = config.override({"renderer": {"backend": "raster"}, "camera": {"width": 160, "height": 120}})
    intrinsics = Intrinsics.from_config(config.camera)
    with RasterRenderer(scene, config, intrinsics) as whole:
        expected, whole_geoms = whole.render(pose), whole.model.ngeom
    assert whole_geoms > 10_000  # past the fixed buffer mujoco.Renderer would have drawn
    with RasterRenderer(scene, config, intrinsics, pose[None, :3, 3]) as culled:
        frame, culled_geoms = culled.render(pose), culled.model.ngeom
        drawn = np.count_nonzero(culled.model.geom_group != HIDDEN)
        culled.sides = np.zeros((4, 3))  # every side of the frustum passes: each geom in reach is drawn
        every = culled.render(pose)
        assert np.count_nonzero(culled.model.geom_group != HIDDEN) > 2 * drawn
    assert culled_geoms < whole_geoms / 2
    # a frame draws only the geoms inside its frustum, or whose shadow is, and is the frame of all those in reach
    for name in ("rgb", "depth", "mask"):
        assert np.array_equal(getattr(frame, name), getattr(every, name))
    assert np.array_equal(frame.mask, expected.mask) and len(np.unique(frame.mask)) > 3
    # MuJoCo stores a mesh about its centre in float32: the copies' merged fruit stalks and calyces, of fewer plants
    # in the culled build, have another centre, so their vertices differ in the last bit, and the pixels they decide
    np.testing.assert_allclose(frame.depth, expected.depth, rtol=0, atol=1e-5)
    difference = np.abs(frame.rgb.astype(int) - expected.rgb)
    assert difference.max() <= 1 and np.count_nonzero(difference) < 0.002 * difference.size


def test_a_culled_cycles_frame_matches_the_whole_scenes_frame_with_fewer_objects(view):
    import bpy

    from renderloop.render.camera import Intrinsics
    from renderloop.render.cycles import CyclesRenderer

    config, scene, pose = view
    config = config.override({"camera": {"width": 80, "height": 60},
                              "renderer": {"backend": "cycles", "samples": 1, "denoise": False, "device": "cpu"}})
    intrinsics = Intrinsics.from_config(config.camera)
    with CyclesRenderer(scene, config, intrinsics) as whole:
        expected, whole_objects = whole.render(pose), len(bpy.data.objects)
    with CyclesRenderer(scene, config, intrinsics, pose[None, :3, 3]) as culled:
        frame, culled_objects = culled.render(pose), len(bpy.data.objects)
    assert culled_objects < whole_objects
    assert np.array_equal(frame.mask, expected.mask)
    np.testing.assert_allclose(frame.depth, expected.depth, rtol=0, atol=1e-5)
    # a path of the one sample that bounced off a dropped plant, or was shaded by it, now goes on to the sky: those
    # pixels (2 % of this frame's values, 1.5 levels brighter on average over the frame) differ, the rest are the same
    difference = np.abs(frame.rgb.astype(int) - expected.rgb)
    assert np.count_nonzero(difference) < 0.05 * difference.size and difference.mean() < 3.0
