"""Rendering with the raster backend (fast); tests/test_cycles.py holds the real Cycles renders."""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import fly_demo_raster

from renderloop.config import load_config
from renderloop.errors import UserError
from renderloop.parallel import Executor
from renderloop.render.camera import Intrinsics, read_camera_info, to_gl_camera
from renderloop.render.frames import read_frame
from renderloop.render.raster import RasterRenderer
from renderloop.render.stage import run_render
from renderloop.robot.kinematics import camera_rotation, homogeneous, look_at
from renderloop.rundir.files import read_config, read_poses


def wall_depth(intrinsics: Intrinsics, pose: np.ndarray, wall_x: float) -> np.ndarray:
    """Analytic planar depth of the plane x = wall_x for every pixel."""
    u, v = np.meshgrid(np.arange(intrinsics.width), np.arange(intrinsics.height))
    rays = np.stack([(u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy, np.ones_like(u, float)], axis=-1)
    world_x = rays @ pose[:3, :3][0]
    return (wall_x - pose[0, 3]) / world_x


@pytest.fixture(scope="module")
def raster(demo):
    config, scene = demo
    intrinsics = Intrinsics.from_config(config.camera)
    with RasterRenderer(scene, config, intrinsics) as renderer:
        yield config, scene, intrinsics, renderer


@pytest.mark.parametrize("yaw_deg", [0.0, 30.0])
def test_depth_of_a_plane_at_a_known_distance(raster, yaw_deg):
    config, scene, intrinsics, renderer = raster
    wall_x = scene.room[0] / 2
    pose = homogeneous(camera_rotation(math.radians(yaw_deg), 0.0), (wall_x - 1.5, -1.0, 1.6))
    frame = renderer.render(pose)
    expected = wall_depth(intrinsics, pose, wall_x)
    centre = (intrinsics.height // 2, intrinsics.width // 2)
    assert frame.depth.min() > 0
    assert abs(frame.depth[centre] - expected[centre]) < 1e-3
    assert np.abs(frame.depth / expected - 1).max() < 0.005
    assert not frame.mask.any()


def test_intrinsics_project_and_back_project():
    intrinsics = Intrinsics.from_config(load_config("paper").camera)
    assert (intrinsics.cx, intrinsics.cy) == (319.5, 239.5)
    points = np.array([[0.1, -0.2, 1.5], [0.0, 0.0, 0.7], [-0.3, 0.25, 2.0]])
    pixels = intrinsics.project(points)
    assert np.allclose(pixels[1], [319.5, 239.5])
    assert np.allclose(intrinsics.back_project(pixels, points[:, 2]), points)
    gl = to_gl_camera(homogeneous(camera_rotation(0.3, 0.2), (1, 2, 3)))
    assert np.allclose(-gl[:3, 2], camera_rotation(0.3, 0.2)[:, 2])  # the GL camera looks down its -z


def test_pepper_pixels_are_on_the_pepper(raster):
    config, scene, intrinsics, renderer = raster
    seen = 0
    for pepper in scene.peppers:
        side = -1.0 if pepper.side == "left" else 1.0
        camera = np.array(pepper.center) + np.array([side * 0.45, 0.05, 0.08])
        pose = look_at(camera, pepper.center)
        frame = renderer.render(pose)
        world_to_camera = np.linalg.inv(pose)
        centre = world_to_camera[:3, :3] @ pepper.center + world_to_camera[:3, 3]
        u, v = np.rint(intrinsics.project(centre)[0]).astype(int)
        if frame.mask[v, u] == pepper.id:
            assert centre[2] - pepper.radius - 0.01 <= frame.depth[v, u] <= centre[2] + 0.01
            seen += 1
        for pid in np.unique(frame.mask[frame.mask > 0]):
            other = next(p for p in scene.peppers if p.id == pid)
            rows, cols = np.nonzero(frame.mask == pid)
            points = intrinsics.back_project(np.column_stack([cols, rows]), frame.depth[rows, cols])
            world = (pose[:3, :3] @ points.T).T + pose[:3, 3]
            assert np.linalg.norm(world - other.center, axis=1).max() <= 1.5 * other.radius
    assert seen >= len(scene.peppers) // 2


@pytest.fixture(scope="module")
def flown_once(tmp_path_factory) -> Path:
    return fly_demo_raster(tmp_path_factory.mktemp("flown") / "run")


@pytest.fixture()
def flown(flown_once: Path, tmp_path: Path) -> Path:
    """A copy of the demo planned and flown, not yet rendered, for a test to change."""
    return Path(shutil.copytree(flown_once, tmp_path / "run"))


def _files(run_dir: Path) -> dict[str, bytes]:
    names = ("rgb", "depth", "depth_sensor", "masks")
    return {f"{d}/{p.name}": p.read_bytes() for d in names for p in sorted((run_dir / d).iterdir())} | {
        name: (run_dir / name).read_bytes() for name in ("rgb.txt", "depth.txt", "camera_info.yaml")
    }


def test_render_writes_the_run_files(flown: Path):
    config = read_config(flown)
    assert run_render(flown, config)
    times, poses = read_poses(flown)
    assert len(list((flown / "rgb").iterdir())) == len(poses)
    rgb_index = [line.split() for line in (flown / "rgb.txt").read_text().splitlines() if not line.startswith("#")]
    assert [float(t) for t, _ in rgb_index] == pytest.approx(times) and rgb_index[0][1] == "rgb/000000.png"
    assert read_camera_info(flown) == Intrinsics.from_config(config.camera)
    frame = read_frame(flown, 3)
    assert frame.rgb.shape == (config.camera.height, config.camera.width, 3)
    assert frame.depth.dtype == np.float32 and frame.mask.dtype == np.uint16
    assert not run_render(flown, config)  # complete: skipped


def test_killed_render_resumes_to_the_same_files(flown: Path, tmp_path: Path):
    config = read_config(flown)
    reference = tmp_path / "reference"
    shutil.copytree(flown, reference)
    run_render(reference, config)

    class Killed(Exception):
        pass

    def die_after_five(done: int, total: int) -> None:
        if done >= 5:
            raise Killed

    with pytest.raises(Killed):
        run_render(flown, config, progress=die_after_five)
    assert not (flown / "rgb.txt").exists()
    assert run_render(flown, config)
    assert _files(flown) == _files(reference)
    assert not list(flown.rglob("*.partial"))


def test_changed_poses_start_the_render_over(flown: Path):
    config = read_config(flown)
    run_render(flown, config)
    text = (flown / "groundtruth.txt").read_text().splitlines()
    (flown / "groundtruth.txt").write_text("\n".join(line for line in text if not line.startswith("#"))[: -1] + "1\n")
    assert run_render(flown, config)  # the last pose moved a little: the frames were redone, not reused


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("", "holds no poses"),
        ("# only a comment\n", "holds no poses"),
        ("0.0 1 2 3 0 0 0 1\n0.2 1 2 nan 0 0 0 1\n", "pose 1 (t=0.2) has NaN"),
        ("0.0 1 2 3 0 0 0 2\n", "not unit length"),
        ("0.0 1 2 3\n", "expected lines of 8 numbers"),
    ],
)
def test_bad_groundtruth_is_refused(flown: Path, content: str, message: str):
    (flown / "groundtruth.txt").write_text(content)
    with pytest.raises(UserError, match=re.escape(message)):
        run_render(flown, read_config(flown))


def test_unknown_backend_and_unanswering_ray(flown: Path):
    config = read_config(flown)
    with pytest.raises(UserError, match="unknown backend 'opengl'"):
        config.override({"renderer": {"backend": "opengl"}}, "unknown backend 'opengl'")
    with pytest.raises(UserError, match="--address 127.0.0.1:1: no Ray cluster answers there"):
        run_render(flown, config, executor=Executor(kind="ray", address="127.0.0.1:1"))


def test_a_render_that_cannot_fit_on_the_disk_is_refused_before_its_first_frame(flown: Path, monkeypatch):
    from renderloop.io import disk

    usage = shutil.disk_usage(flown)
    monkeypatch.setattr(disk.shutil, "disk_usage", lambda _: usage._replace(free=10_000))
    with pytest.raises(UserError, match=r"frames of 320x240 need up to 0\.\d GB but the disk has 0\.0 GB free"):
        run_render(flown, read_config(flown))
    assert not (flown / "rgb").exists() and not (flown / "rgb.txt").exists()


def test_raster_colours_come_from_the_material_table(raster):
    import mujoco

    from renderloop.scene.materials import display_rgba

    config, scene, intrinsics, renderer = raster
    model = renderer.model
    for geom, material in (("floor", "floor"), ("wall_east", "wall"), ("table_0", "table"), ("workstation_arm", "workstation")):
        assert tuple(model.geom_rgba[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)]) == pytest.approx(display_rgba(material))
    pot = model.geom_rgba[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "pot_0")]
    assert tuple(pot) == pytest.approx(display_rgba("pot"))
    pepper = scene.peppers[0]
    assert tuple(model.geom_rgba[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"pepper_{pepper.id}")]) == pytest.approx((*pepper.rgb, 1))


def test_the_raster_look_with_shadows_or_without_antialiasing_changes_the_colour_alone(raster):
    config, scene, intrinsics, renderer = raster
    plant = scene.plants[0]
    pose = look_at(np.array(plant.position) + (0.0, -0.7, 0.5), np.array(plant.position) + (0.0, 0.0, 0.2))
    before = renderer.render(pose)

    def render(**look) -> np.ndarray:
        with RasterRenderer(scene, config.override({"renderer": {"raster": look}}), intrinsics) as other:
            frame = other.render(pose)
        assert np.array_equal(before.depth, frame.depth) and np.array_equal(before.mask, frame.mask)
        return frame.rgb.astype(int).sum(axis=2) - before.rgb.astype(int).sum(axis=2)

    shadowed = render(shadows=True)
    assert (shadowed < -30).mean() > 0.01 and shadowed.max() < 20  # shadowed pixels darker, none lit but at an edge
    aliased = render(antialias=0)
    assert 0 < (aliased != 0).mean() < 0.1  # edges, no longer blended


def test_the_raster_sun_casts_its_shadows_wherever_the_camera_looks(raster):
    """The sun's shadow map follows the camera: looking down on each plant of the row, from one end of the room to the
    other, its shadow darkens the bench beside it."""
    config, scene, intrinsics, renderer = raster
    with RasterRenderer(scene, config.override({"renderer": {"raster": {"shadows": True}}}), intrinsics) as shadowed:
        for plant in scene.plants:
            pose = look_at(np.array(plant.position) + (0.0, -0.3, 1.5), np.array(plant.position))
            darker = shadowed.render(pose).rgb.astype(int).sum(axis=2) < renderer.render(pose).rgb.astype(int).sum(axis=2) - 30
            assert darker.mean() > 0.02, plant.id


def test_the_render_device_is_not_part_of_the_record(flown: Path):
    """Like the thread count, the device decides how fast frames come, not what they hold."""
    from renderloop.rundir.files import check_config

    config = read_config(flown)
    assert run_render(flown, config)
    gpu = config.override({"renderer": {"device": "gpu"}})
    check_config(flown, gpu)  # the same run
    assert not run_render(flown, gpu)  # the same frames: nothing to redo
    assert "device" not in json.loads((flown / "render.json").read_text())["renderer"]
