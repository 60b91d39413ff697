"""Cycles and the raster backend see the same scene: the same peppers where, the same depths, in both plant
styles (the 'pepper' style's leaves are instances in Cycles and one merged mesh in the raster view)."""

from __future__ import annotations

import numpy as np
import pytest

from renderloop.config import load_config
from renderloop.render.camera import Intrinsics
from renderloop.render.cycles import CyclesRenderer
from renderloop.render.raster import RasterRenderer
from renderloop.robot.kinematics import look_at
from renderloop.scene.generate import generate_scene


@pytest.fixture(scope="module", params=["simple", "pepper"])
def both(request):
    config = load_config("demo").override({"plants": {"style": request.param}, "camera": {"width": 160, "height": 120},
                                           "renderer": {"samples": 4, "denoise": False}})
    scene = generate_scene(config)
    intrinsics = Intrinsics.from_config(config.camera)
    plant = scene.plants[1]
    target = np.array([plant.position[0], plant.position[1], plant.bounds.max[2] - 0.2])
    pose = look_at(target + np.array([-0.45, -0.1, 0.05]), target)  # where a left-side scan puts the camera
    with CyclesRenderer(scene, config, intrinsics) as cycles, RasterRenderer(scene, config, intrinsics) as raster:
        return cycles.render(pose), raster.render(pose)


def test_masks_agree(both):
    cycles, raster = both
    a, b = cycles.mask > 0, raster.mask > 0
    assert a.sum() > 200  # peppers are in view
    assert (a & b).sum() / (a | b).sum() >= 0.9
    same_pixels = a & b
    assert np.mean(cycles.mask[same_pixels] == raster.mask[same_pixels]) > 0.99  # and they are the same peppers


def test_depths_agree(both):
    cycles, raster = both
    valid = (cycles.depth > 0) & (raster.depth > 0)
    assert valid.mean() > 0.5
    assert np.median(np.abs(cycles.depth[valid] - raster.depth[valid])) < 0.005
