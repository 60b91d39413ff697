"""Real Cycles renders, tiny and few samples: the depth, projection and mask conventions hold."""

from __future__ import annotations

import math

import numpy as np
import pytest

from renderloop.config import load_config
from renderloop.parallel import Executor
from renderloop.render.camera import Intrinsics
from renderloop.render.cycles import CyclesRenderer
from renderloop.robot.kinematics import camera_rotation, homogeneous, look_at
from renderloop.scene import meshes
from renderloop.scene.generate import generate_scene


def small_config(width: int = 96, height: int = 72):
    return load_config("demo").override({"camera": {"width": width, "height": height}, "renderer": {"samples": 4, "denoise": False}})


def plane_depth(intrinsics: Intrinsics, pose: np.ndarray, point: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Analytic planar depth of the plane through `point` with `normal`, per pixel."""
    u, v = np.meshgrid(np.arange(intrinsics.width), np.arange(intrinsics.height))
    rays = np.stack([(u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy, np.ones(u.shape)], axis=-1)
    world = rays @ pose[:3, :3].T
    return ((point - pose[:3, 3]) @ normal) / (world @ normal)


@pytest.mark.parametrize("tilt_deg", [0.0, 30.0])
def test_depth_of_a_plane_at_a_known_distance(tilt_deg):
    config = small_config()
    intrinsics = Intrinsics.from_config(config.camera)
    tilt = math.radians(tilt_deg)
    normal = np.array([-math.cos(tilt), math.sin(tilt), 0.0])  # facing the camera, turned about z
    centre = np.array([1.5, 0.0, 1.0])
    quad = meshes.box(centre, (0.002, 6.0, 6.0))
    rotation = np.array([[math.cos(tilt), math.sin(tilt), 0], [-math.sin(tilt), math.cos(tilt), 0], [0, 0, 1]])
    plane = quad.transformed(rotation, centre - rotation @ centre)
    pose = homogeneous(camera_rotation(0.0, 0.0), (0.0, 0.0, 1.0))
    face = centre - 0.001 * rotation[:, 0]  # the box's face towards the camera
    with CyclesRenderer.from_objects([("plane", plane, (0.5, 0.5, 0.5), 0)], config, intrinsics) as renderer:
        frame = renderer.render(pose)
    expected = plane_depth(intrinsics, pose, face, normal)
    middle = (intrinsics.height // 2, intrinsics.width // 2)
    assert frame.depth.min() > 0
    assert abs(frame.depth[middle] - expected[middle]) < 1e-3
    assert np.abs(frame.depth / expected - 1).max() < 0.005


def test_a_point_projects_where_the_intrinsics_say():
    config = small_config(120, 90)
    intrinsics = Intrinsics.from_config(config.camera)
    pose = homogeneous(camera_rotation(0.2, -0.1), (0.3, -0.2, 1.1))
    target_optical = np.array([0.12, -0.07, 1.2])
    target = pose[:3, :3] @ target_optical + pose[:3, 3]
    heights = np.linspace(-0.999, 0.999, 41) * 0.02
    ball = meshes.tube(target + np.column_stack([0 * heights, 0 * heights, heights]), np.sqrt(0.02**2 - heights**2), sides=48)
    backdrop = meshes.box(pose[:3, :3] @ np.array([0, 0, 5.0]) + pose[:3, 3], (4, 4, 4))  # a wall 3 m away
    objects = [("ball", ball, (0.8, 0.1, 0.1), 7), ("wall", backdrop, (0.6, 0.6, 0.6), 0)]
    with CyclesRenderer.from_objects(objects, config, intrinsics) as renderer:
        frame = renderer.render(pose)
    rows, cols = np.nonzero(frame.mask == 7)
    assert len(rows) > 10
    u, v = intrinsics.project(target_optical)[0]
    assert abs(cols.mean() - u) < 0.5 and abs(rows.mean() - v) < 0.5
    nearest = int(np.rint(v)), int(np.rint(u))
    assert frame.mask[nearest] == 7
    assert frame.depth[nearest] == pytest.approx(target_optical[2] - 0.02, abs=3e-3)  # the near surface


@pytest.fixture(scope="module")
def greenhouse():
    config = small_config(160, 120)
    scene = generate_scene(config)
    intrinsics = Intrinsics.from_config(config.camera)
    pepper = scene.peppers[0]
    side = -1.0 if pepper.side == "left" else 1.0
    pose = look_at(np.array(pepper.center) + np.array([side * 0.45, 0.05, 0.08]), pepper.center)
    with CyclesRenderer(scene, config, intrinsics) as renderer:
        frames = [renderer.render(pose), renderer.render(pose)]
    return scene, intrinsics, pose, pepper, frames


def test_greenhouse_frame_masks_and_depth_agree_with_the_scene(greenhouse):
    scene, intrinsics, pose, pepper, (frame, _) = greenhouse
    assert pepper.id in frame.mask
    world_to_camera = np.linalg.inv(pose)
    centre = world_to_camera[:3, :3] @ pepper.center + world_to_camera[:3, 3]
    u, v = np.rint(intrinsics.project(centre)[0]).astype(int)
    assert frame.mask[v, u] == pepper.id
    assert centre[2] - pepper.radius - 0.01 <= frame.depth[v, u] <= centre[2] + 0.01
    for pid in np.unique(frame.mask[frame.mask > 0]):
        other = next(p for p in scene.peppers if p.id == pid)
        rows, cols = np.nonzero(frame.mask == pid)
        points = intrinsics.back_project(np.column_stack([cols, rows]), frame.depth[rows, cols])
        world = points @ pose[:3, :3].T + pose[:3, 3]
        assert np.linalg.norm(world - other.center, axis=1).max() <= 1.5 * other.radius


def test_same_scene_and_pose_same_images(greenhouse):
    *_, (first, second) = greenhouse
    assert np.array_equal(first.rgb, second.rgb)
    assert np.array_equal(first.depth, second.depth)
    assert np.array_equal(first.mask, second.mask)
    assert first.timings["render_time"] > 0 and first.timings["total"] >= first.timings["render_time"]
    assert first.rgb.std() > 10  # an image, not a blank


def test_cycles_workers_start_after_blender_was_imported_here(tmp_path):
    """Two spawned Cycles workers, from a process that already holds bpy, render the same files as one."""
    import os

    import bpy  # noqa: F401  (what a notebook user will have done)

    from renderloop.planning.stage import run_plan
    from renderloop.render.stage import run_render
    from renderloop.scene.stage import run_scene
    from renderloop.sim.stage import run_fly

    config = small_config(64, 48).override({"camera": {"rate_hz": 0.05}})  # 5 frames
    one, two = tmp_path / "one", tmp_path / "two"
    for stage in (run_scene, run_plan, run_fly):
        stage(one, config)
    os.system(f"cp -r {one} {two}")
    run_render(one, config)
    run_render(two, config, executor=Executor(workers=2))
    for name in ("rgb", "depth", "masks"):
        assert [p.read_bytes() for p in sorted((one / name).iterdir())] == [p.read_bytes() for p in sorted((two / name).iterdir())]


def test_off_centre_principal_point_and_cleanup():
    """The camera shift puts the optical axis at (cx, cy); the sky is no return; close() cleans up."""
    config = small_config(120, 90)
    base = Intrinsics.from_config(config.camera)
    intrinsics = Intrinsics(base.width, base.height, base.fx, base.fy, base.cx + 3.5, base.cy - 2.25)
    pose = homogeneous(camera_rotation(0.0, 0.0), (0.0, 0.0, 1.0))
    target_optical, radius = np.array([0.1, 0.05, 0.8]), 0.03
    target = pose[:3, :3] @ target_optical + pose[:3, 3]
    heights = np.linspace(-0.999, 0.999, 41) * radius
    ball = meshes.tube(target + np.column_stack([0 * heights, 0 * heights, heights]), np.sqrt(radius**2 - heights**2), sides=48)
    with CyclesRenderer.from_objects([("ball", ball, (0.8, 0.1, 0.1), 7)], config, intrinsics) as renderer:
        frame = renderer.render(pose)
        temp = renderer._tmp
    rows, cols = np.nonzero(frame.mask == 7)
    u, v = intrinsics.project(target_optical)[0]
    assert abs(cols.mean() - u) < 0.5 and abs(rows.mean() - v) < 0.5
    assert set(np.unique(frame.mask)) == {0, 7}
    assert np.all(frame.depth[frame.mask == 0] == 0)
    assert not temp.exists()
    with pytest.raises(RuntimeError):
        renderer.render(pose)


def test_a_fresh_renderer_gives_the_same_frame(greenhouse):
    scene, intrinsics, pose, _, (first, _) = greenhouse
    with CyclesRenderer(scene, small_config(160, 120), intrinsics) as renderer:
        again = renderer.render(pose)
    assert np.array_equal(first.rgb, again.rgb)
    assert np.array_equal(first.depth, again.depth)
    assert np.array_equal(first.mask, again.mask)


def test_header_times_parse():
    from renderloop.render.cycles import _seconds

    assert _seconds("00:00.18") == pytest.approx(0.18)
    assert _seconds("01:02.50") == pytest.approx(62.5)
    assert _seconds("1:00:00.00") == pytest.approx(3600.0)
    assert math.isnan(_seconds(None))


def test_device_auto_falls_back_to_the_cpu_and_gpu_is_refused_in_one_line():
    """On a machine without a CUDA or OptiX GPU (the test machines): `auto` renders on the CPU, the same frame as
    `cpu`, and says so; `gpu` is one UserError line."""
    from renderloop.errors import UserError

    def with_device(device: str):
        return small_config(64, 48).override({"renderer": {"device": device}})

    pose = homogeneous(camera_rotation(0.0, 0.0), (0.0, 0.0, 1.0))
    cube = [("cube", meshes.box((1.5, 0.0, 1.0), (0.3, 0.3, 0.3)), (0.8, 0.1, 0.1), 7)]
    intrinsics = Intrinsics.from_config(small_config(64, 48).camera)
    frames = {}
    for device in ("cpu", "auto"):
        with CyclesRenderer.from_objects(cube, with_device(device), intrinsics) as renderer:
            if device == "auto" and renderer.device != "cpu":
                pytest.skip(f"this machine has a GPU ({renderer.device}: {renderer.device_names})")
            assert renderer.device == "cpu" and renderer.device_names == []
            frames[device] = renderer.render(pose)
    assert np.array_equal(frames["auto"].rgb, frames["cpu"].rgb) and 7 in frames["auto"].mask
    with pytest.raises(UserError, match=r"^renderer\.device: gpu, but Cycles finds no CUDA or OptiX GPU") as refused:
        CyclesRenderer.from_objects(cube, with_device("gpu"), intrinsics)
    assert "\n" not in str(refused.value)


def test_gpu_without_a_gpu_is_the_same_one_line_from_worker_processes():
    from renderloop.errors import UserError
    from renderloop.render.cycles import _gpu_devices
    from renderloop.render.executor import render_frames

    if _gpu_devices() is not None:
        pytest.skip("this machine has a GPU")
    config = small_config(32, 24).override({"renderer": {"device": "gpu"}})
    scene = generate_scene(config)
    poses = np.stack([homogeneous(camera_rotation(0.0, 0.0), (0.0, 0.0, 1.0))] * 2)
    with pytest.raises(UserError, match=r"^renderer\.device: gpu, but Cycles finds no CUDA or OptiX GPU"):
        list(render_frames(config, scene, poses, [0, 1], Executor(workers=2)))


def test_cycles_materials_are_built_from_the_table(monkeypatch):
    """Changing a material is one step: the table's numbers reach the node tree."""
    import dataclasses

    from renderloop.render import materials as looks
    from renderloop.scene import materials as table

    monkeypatch.setitem(table.MATERIALS, "wall", dataclasses.replace(table.MATERIALS["wall"], base_rgb=(0.2, 0.4, 0.6), roughness=0.3))
    built = looks.greenhouse_materials()
    drawn = {name for name, look in table.MATERIALS.items() if look.recipe}
    assert set(built) == drawn | {looks.per_vertex_name(name) for name in drawn if table.MATERIALS[name].recipe == "pepper_leaf"}
    principled = next(n for n in built["wall"].node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    assert tuple(principled.inputs["Base Color"].default_value)[:3] == pytest.approx(looks.srgb_to_linear((0.2, 0.4, 0.6)))
    assert principled.inputs["Roughness"].default_value == pytest.approx(0.3)
    pepper = next(n for n in built["pepper_red"].node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    assert pepper.inputs["Coat Weight"].default_value == pytest.approx(table.MATERIALS["pepper_red"].coat)
