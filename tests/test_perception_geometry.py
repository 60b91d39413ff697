"""Organised point clouds and 3D fruit points, on raster frames with boxes from the truth masks."""

from __future__ import annotations

import numpy as np
import pytest

from renderloop.perception.fruit_points import fruit_point, ripe_coloured
from renderloop.perception.pointcloud import organised_cloud, to_world
from renderloop.render.camera import Intrinsics
from renderloop.render.raster import RasterRenderer
from renderloop.robot.kinematics import look_at
from renderloop.scene.plant import BASE_RGB


def test_cloud_is_the_back_projection_with_nan_for_no_return():
    intrinsics = Intrinsics(8, 6, 5.0, 5.0, 3.5, 2.5)
    depth = np.linspace(0.5, 2.0, 48, dtype=np.float32).reshape(6, 8)
    depth[2, 3] = 0.0
    cloud = organised_cloud(depth, intrinsics)
    assert cloud.shape == (6, 8, 3) and cloud.dtype == np.float32
    assert np.isnan(cloud[2, 3]).all()
    v, u = np.mgrid[0:6, 0:8]
    valid = depth > 0
    expected = intrinsics.back_project(np.column_stack([u[valid], v[valid]]), depth[valid])
    assert np.allclose(cloud[valid], expected, atol=1e-6)
    with pytest.raises(ValueError, match="depth is 8x6 but the camera is 9x6"):
        organised_cloud(depth, Intrinsics(9, 6, 5.0, 5.0, 4.0, 2.5))


@pytest.fixture(scope="module")
def frames(demo):
    """Raster frames from scan-like poses around every plant, with their poses."""
    config, scene = demo
    intrinsics = Intrinsics.from_config(config.camera)
    shots = []
    with RasterRenderer(scene, config, intrinsics) as renderer:
        for plant in scene.plants:
            centre = np.array([plant.position[0], plant.position[1], plant.bounds.max[2] - 0.22])
            for side in (-1, 1):
                for dz in (-0.15, 0.0, 0.15):
                    pose = look_at(centre + np.array([side * 0.44, 0.05, dz]), centre)
                    shots.append((pose, renderer.render(pose)))
    return config, scene, intrinsics, shots


def test_the_cloud_of_a_rendered_frame_lands_on_the_scene(frames):
    config, scene, intrinsics, shots = frames
    pose, frame = shots[0]
    world = to_world(organised_cloud(frame.depth, intrinsics), pose)
    for pepper in scene.peppers:
        pixels = frame.mask == pepper.id
        if pixels.sum() > 20:
            distance = np.linalg.norm(world[pixels] - np.array(pepper.center, dtype=np.float32), axis=1)
            assert distance.max() <= 1.5 * pepper.radius


def test_fruit_points_from_truth_boxes_lie_on_their_pepper(frames):
    config, scene, intrinsics, shots = frames
    errors = []
    for pose, frame in shots:
        cloud = organised_cloud(frame.depth, intrinsics)
        for pid in np.unique(frame.mask[frame.mask > 0]):
            rows, cols = np.nonzero(frame.mask == pid)
            if len(rows) < 150:  # a sliver at the image edge or behind leaves: no box a detector would give
                continue
            pepper = next(p for p in scene.peppers if p.id == pid)
            point = fruit_point(cloud, (cols.min(), rows.min(), cols.max() + 1, rows.max() + 1), intrinsics.fx)
            assert point is not None
            world = pose[:3, :3] @ point + pose[:3, 3]
            errors.append(np.linalg.norm(world - pepper.center) / pepper.radius)
    errors = np.array(errors)
    assert len(errors) > 50
    assert np.mean(errors <= 1.0) >= 0.9  # on the pepper (its bounding sphere) for nine boxes in ten
    assert np.median(errors) < 0.4  # the centre, not the skin: the skin's centroid alone sat at 0.6-0.7 radii


def test_an_empty_box_has_no_fruit_point():
    cloud = np.full((10, 10, 3), np.nan, dtype=np.float32)
    assert fruit_point(cloud, (2, 2, 8, 8), 500.0) is None


def test_ripe_colour_tells_fruit_from_the_greenhouse():
    ripe = [BASE_RGB[name] for name in ("red", "orange", "yellow")] + [(0.2, 0.02, 0.02)]  # the last: red in shade
    other = [BASE_RGB["green"], (0.10, 0.32, 0.06), (0.2, 0.4, 0.1),  # green fruit, leaf, stem
             (0.45, 0.62, 0.9), (0.86, 0.88, 0.9), (0.5, 0.48, 0.44), (0.06, 0.06, 0.065)]  # sky, wall, floor, pot
    pixels = (np.array(ripe + other)[None] * 255).round().astype(np.uint8)
    assert ripe_coloured(pixels)[0].tolist() == [True] * len(ripe) + [False] * len(other)


def test_a_stem_across_a_ripe_fruit_does_not_pull_its_point_off():
    """A fruit 0.5 m away behind a stem 10 cm in front of it that fills most of the box's centre:
    by depth alone the stem wins; the fruit's colour keeps the point on the fruit."""
    intrinsics = Intrinsics(60, 60, 300.0, 300.0, 29.5, 29.5)
    v, u = np.mgrid[0:60, 0:60]
    fruit = (u - 29.5) ** 2 + (v - 29.5) ** 2 <= 20**2
    stem = fruit & (np.abs(u - 29.5) < 9)
    depth = np.where(fruit, 0.5, 2.0).astype(np.float32)
    depth[stem] = 0.4
    cloud = organised_cloud(depth, intrinsics)
    box = (9.5, 9.5, 50.5, 50.5)
    assert fruit_point(cloud, box, intrinsics.fx)[2] < 0.45  # the stem
    point = fruit_point(cloud, box, intrinsics.fx, fruit & ~stem)
    assert 0.5 < point[2] < 0.5 + 0.05  # on the fruit, moved towards its centre
