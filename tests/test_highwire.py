"""The 'highwire' plant style of the greenhouse preset: stems trained up strings, the fruit clear of them."""

from __future__ import annotations

import numpy as np
import pytest

from renderloop.config import Config, load_config
from renderloop.scene.generate import generate_scene
from renderloop.scene.objects import collision_objects, environment_objects
from renderloop.scene.pepper_plant import _along


def highwire_config(seed: int) -> Config:
    # the stems and fruit as in the preset, fewer leaves: fast
    return load_config("greenhouse", seed=seed).override({"plants": {"pepper_style": {"leaves": [60, 90]}}})


@pytest.fixture(scope="module")
def scenes():
    return [(config, generate_scene(config)) for config in map(highwire_config, (0, 1, 2))]


def test_the_greenhouse_preset_grows_two_to_four_stems_per_plant_each_winding_up_its_string(scenes):
    for config, scene in scenes:
        style = config.plants.highwire
        assert config.plants.style == "highwire"
        for plant in scene.plants:
            feet = np.array(plant.strings)
            assert style.stems[0] <= len(feet) <= style.stems[1]
            stems = [tube for tube in plant.branches if len(tube.points) > 10]  # the side shoots are one internode
            assert len(stems) == len(feet)
            for stem in stems:
                points = np.array(stem.points)
                assert np.ptp(points[:, 2]) > 0.75 * config.plants.volume[2]  # it climbs the whole canopy
                climbed = points[2:]  # past its way over from the fork
                off = np.linalg.norm(climbed[:, None, :2] - feet[None, :, :2], axis=2).min(axis=1)
                assert off.max() <= style.wind * 1.6 + 1e-6
                assert np.all(np.diff(points[:, 2]) > 0)  # node above node
            assert all(plant.bounds.contains(tuple(foot)) for foot in feet)


def test_no_stem_cuts_into_a_fruit_and_every_leaf_is_above_the_stripped_stems(scenes):
    for config, scene in scenes:
        for plant in scene.plants:
            fruit = [pepper for pepper in scene.peppers if pepper.plant == plant.id]
            centers, radii = np.array([p.center for p in fruit]), np.array([p.radius for p in fruit])
            for stem in (tube for tube in plant.branches if len(tube.points) > 10):
                samples = _along(np.array(stem.points), 0.005)
                gap = np.linalg.norm(samples[:, None] - centers[None], axis=2) - radii[None]
                assert gap.min() > stem.radius
            floor = plant.position[2] + plant.pot.height + config.plants.highwire.leafless * config.plants.volume[2]
            assert min(leaf.base[2] for leaf in plant.leaves) >= floor - 0.08  # a leaf may start on the last stripped internode


def test_each_string_runs_from_its_stem_foot_to_the_crop_wire_in_the_flight_volume_and_over_the_neighbours(scenes):
    _, scene = scenes[0]
    wire = scene.environment.wire_height
    inside = [shape for obj in collision_objects(scene) if obj.name == "wires" for shape in obj.shapes
              if shape.name.startswith("string_")]
    feet = [tuple(foot) for plant in scene.plants for foot in plant.strings]
    assert sorted(tuple(shape.start) for shape in inside) == sorted(feet)
    assert all(shape.end[2] == wire and shape.end[:2] == shape.start[:2] for shape in inside)
    neighbours = [shape for obj in environment_objects(scene) if obj.name == "wires" for shape in obj.shapes
                  if shape.name.startswith("string_bg")]
    prototypes = scene.environment.prototypes
    per_copy = sum(len(prototypes[copy.prototype].plant.strings) for copy in scene.environment.plants)
    assert len(neighbours) == per_copy + len(scene.environment.traps)
