"""The raster view draws the greenhouse Cycles draws: its floor and walls in the material table's colours, and where
nothing lies in the clip range Cycles' world (the plain room's sky, the film greenhouse's glow), not OpenGL's black;
depth and masks stay exact."""

from __future__ import annotations

import numpy as np
import pytest

from renderloop.config import load_config
from renderloop.render.camera import Intrinsics
from renderloop.render.cycles import CyclesRenderer
from renderloop.render.raster import RasterRenderer
from renderloop.render.sky import plain_sky_strength, scene_sky
from renderloop.robot.kinematics import look_at
from renderloop.scene.generate import generate_scene
from renderloop.scene.materials import display_rgba

SMALL = {"camera": {"width": 160, "height": 120}, "renderer": {"samples": 4, "denoise": False}}
AISLE = look_at(np.array([-3.0, -3.5, 1.0]), np.array([0.0, -3.5, 0.4]))  # floor ahead, the south wall on the right


def plane_depth(intrinsics: Intrinsics, pose: np.ndarray, axis: int, value: float) -> np.ndarray:
    """Planar depth of every pixel's ray to the world plane where coordinate `axis` equals `value` (NaN: behind)."""
    u, v = np.meshgrid(np.arange(intrinsics.width), np.arange(intrinsics.height))
    rays = np.stack([(u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy, np.ones_like(u, float)], axis=-1)
    along = rays @ pose[:3, :3][axis]  # world coordinate `axis` gained per unit of optical depth
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = (value - pose[axis, 3]) / along
    return np.where(depth > 0, depth, np.nan)


def shade_of(pixels: np.ndarray, material: str) -> np.ndarray:
    """Each pixel's colour over the material's display colour, channel by channel: one number thrice for a surface
    of that colour under white light."""
    return pixels.astype(float) / (255.0 * np.asarray(display_rgba(material)[:3]))


def interior(background: np.ndarray) -> np.ndarray:
    """Background pixels whose 8 neighbours are background too (away from silhouettes, which Cycles' pixel filter
    and the raster's multisamples blend differently; twice for Cycles' filter, which reaches two pixels)."""
    padded = np.pad(background, 1, constant_values=False)
    h, w = background.shape
    return np.all([padded[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1)], axis=0)


@pytest.fixture(scope="module")
def demo_small():
    config = load_config("demo").override(SMALL)
    return config, generate_scene(config), Intrinsics.from_config(config.camera)


@pytest.fixture(scope="module")
def aisle(demo_small):
    """Cycles and raster frames down an empty aisle of the demo greenhouse."""
    config, scene, intrinsics = demo_small
    with CyclesRenderer(scene, config, intrinsics) as cycles, RasterRenderer(scene, config, intrinsics) as raster:
        return cycles.render(AISLE), raster.render(AISLE)


@pytest.fixture(scope="module")
def fruit(demo_small):
    """Cycles and raster frames of a bearing plant from a scan's distance, sky behind its top, and the raster frame
    again without antialiasing."""
    config, scene, intrinsics = demo_small
    plant = scene.plants[1]
    target = np.array([plant.position[0], plant.position[1], plant.bounds.max[2] - 0.2])
    pose = look_at(target + np.array([-0.8, -0.1, 0.3]), target + np.array([0.0, 0.0, 0.25]))
    with CyclesRenderer(scene, config, intrinsics) as cycles, RasterRenderer(scene, config, intrinsics) as raster:
        frames = cycles.render(pose), raster.render(pose)
    with RasterRenderer(scene, config.override({"renderer": {"raster": {"antialias": 0}}}), intrinsics) as aliased:
        return (*frames, aliased.render(pose))


def test_a_raster_frame_down_the_aisle_has_no_black_where_cycles_sees_sky_wall_or_floor(aisle):
    cycles, raster = aisle
    assert not np.all(raster.rgb == 0, axis=2).any()
    sky = (cycles.depth == 0) & (raster.depth == 0)
    assert sky[0].mean() > 0.5 and not sky[-1].any()  # the top row is mostly sky, the bottom row floor
    assert np.mean((cycles.depth == 0) != (raster.depth == 0)) < 0.01  # the same pixels are past the clip range
    inner = interior(interior(sky))
    assert inner.sum() > 1000
    difference = np.abs(cycles.rgb[inner].astype(int) - raster.rgb[inner].astype(int))
    assert difference.max() <= 2  # Cycles' sky colour to the 8-bit level, pixel by pixel


def test_the_sky_gradient_runs_from_a_pale_horizon_to_a_blue_zenith(aisle):
    _, raster = aisle
    sky = raster.depth == 0
    top = raster.rgb[0][sky[0]].astype(int)
    lowest = max(v for v in range(raster.depth.shape[0]) if sky[v].any())
    low = raster.rgb[lowest][sky[lowest]].astype(int)
    assert (top[:, 2] - top[:, 0]).mean() > (low[:, 2] - low[:, 0]).mean() + 5  # bluer up the frame


def test_floor_pixels_have_the_depth_of_the_floor_plane_and_the_floor_colour_of_the_material_table(aisle, demo_small):
    _, raster = aisle
    _, _, intrinsics = demo_small
    floor = plane_depth(intrinsics, AISLE, 2, 0.0)  # the floor's top is the plane z = 0
    on_floor = np.isfinite(floor) & (floor < 5.0) & (np.abs(raster.depth - floor) < 1e-3 * floor)
    assert on_floor[-10:].mean() > 0.6  # the bottom rows see the floor, at its exact depth
    shades = shade_of(raster.rgb[on_floor], "floor")
    assert shades.mean() > 0.5  # lit, not black
    # one shade across the channels: the table's floor colour under white light, not a grey or a wall's colour
    assert np.median(np.ptp(shades, axis=1) / shades.mean(axis=1)) < 0.04


def test_wall_pixels_have_the_depth_of_the_wall_plane_and_the_wall_colour_of_the_material_table(aisle, demo_small):
    _, raster = aisle
    _, scene, intrinsics = demo_small
    wall = plane_depth(intrinsics, AISLE, 1, -scene.room[1] / 2)  # the south wall's inner face
    on_wall = np.isfinite(wall) & (np.abs(raster.depth - wall) < 1e-3 * wall) & (raster.depth > 0)
    assert on_wall[:, -5:].mean() > 0.5  # the right-hand columns see the wall
    shades = shade_of(raster.rgb[on_wall], "wall")
    assert shades.min() > 0.1
    assert np.median(np.ptp(shades, axis=1) / shades.mean(axis=1)) < 0.04


def test_masks_mark_the_fruit_alone_as_cycles_does_and_the_sky_carries_no_id(fruit, demo_small):
    cycles, raster, aliased = fruit
    _, scene, _ = demo_small
    assert (raster.depth == 0).mean() > 0.1  # sky in view
    assert not raster.mask[raster.depth == 0].any()
    assert set(np.unique(raster.mask)) - {0} <= {pepper.id for pepper in scene.peppers}
    a, b = cycles.mask > 0, raster.mask > 0
    assert a.sum() > 100
    assert (a & b).sum() / (a | b).sum() >= 0.9
    assert np.mean(cycles.mask[a & b] == raster.mask[a & b]) > 0.99
    assert np.array_equal(raster.mask, aliased.mask) and np.array_equal(raster.depth, aliased.depth)


def test_antialiased_edges_against_the_sky_blend_into_the_sky_not_into_black(fruit):
    _, raster, aliased = fruit
    sky = raster.depth == 0
    padded = np.pad(sky, 1)
    touches_sky = padded[:-2, 1:-1] | padded[2:, 1:-1] | padded[1:-1, :-2] | padded[1:-1, 2:]
    rim = ~sky & touches_sky
    assert rim.sum() > 50
    # without antialiasing a rim pixel is the geometry's colour; with it, part sky: brighter on average, as the sky
    # is brighter than the crop (a blend with OpenGL's black would make it darker)
    assert raster.rgb[rim].astype(float).mean() > aliased.rgb[rim].astype(float).mean() + 3
    inner = interior(sky)  # open sky: the same with and without antialiasing, but where a sub-pixel leaf crosses it
    assert np.mean(np.all(raster.rgb[inner] == aliased.rgb[inner], axis=1)) > 0.99


@pytest.mark.parametrize("seed", [0, 3, 11])
def test_the_raster_sky_has_the_strength_the_cycles_lighting_draws_from_the_seed(seed):
    config = load_config("demo", seed=seed).override(SMALL)
    with CyclesRenderer.from_objects([], config, Intrinsics.from_config(config.camera), seed=seed) as cycles:
        drawn = cycles.lighting["sky_strength"]
    assert plain_sky_strength(seed) == drawn


def test_the_film_greenhouse_background_is_the_glow_cycles_shows():
    config = load_config("demo").override({**SMALL, "camera": {"width": 80, "height": 60},
                                           "greenhouse": {"environment": {"kind": "film"}}})
    scene = generate_scene(config)
    intrinsics = Intrinsics.from_config(config.camera)
    pose = look_at(np.array([-3.0, 0.0, 1.2]), np.array([-3.0, 8.0, 1.6]))  # down the house, its far end past the clip
    with CyclesRenderer(scene, config, intrinsics) as cycles, RasterRenderer(scene, config, intrinsics) as raster:
        a, b = cycles.render(pose), raster.render(pose)
    assert scene_sky(scene).uniform
    far = (a.depth == 0) & (b.depth == 0)
    assert far.mean() > 0.5
    assert np.array_equal(a.rgb[interior(far)], b.rgb[interior(far)])
    assert not np.all(b.rgb == 0, axis=2).any()
