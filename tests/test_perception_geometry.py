"""Organised point clouds and 3D fruit points, on raster frames with boxes from the truth masks."""

from __future__ import annotations

import numpy as np
import pytest

from renderloop.perception.fruit_points import fruit_point
from renderloop.perception.pointcloud import organised_cloud, to_world
from renderloop.render.camera import Intrinsics
from renderloop.render.raster import RasterRenderer
from renderloop.robot.kinematics import look_at


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
