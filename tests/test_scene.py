from __future__ import annotations

import itertools
from collections import Counter

import numpy as np
import pytest

from renderloop.config import load_config
from renderloop.errors import UserError
from renderloop.io.atomic import dumps_json
from renderloop.scene.generate import generate_scene
from renderloop.scene.model import Scene
from renderloop.scene.plant_meshes import plant_meshes


def _json(scene: Scene) -> str:
    return dumps_json(scene.model_dump(mode="json"))


def test_same_seed_same_bytes_other_seed_other_scene(paper):
    config, scene = paper
    assert _json(generate_scene(config)) == _json(scene)
    other = generate_scene(load_config("paper", seed=config.seed + 1))
    assert _json(other) != _json(scene)
    assert [p.center for p in other.peppers] != [p.center for p in scene.peppers]


def test_paper_scenario_counts(paper):
    _, scene = paper
    assert len(scene.plants) == 32 and len(scene.rows) == 8
    assert all(len(row.plants) == 4 for row in scene.rows)
    bearing = [plant for plant in scene.plants if plant.bearing]
    assert len(bearing) == 20
    for plant in scene.plants:
        sides = Counter(pepper.side for pepper in scene.peppers_of(plant.id))
        if plant.bearing:
            assert 2 <= sum(sides.values()) <= 10
            assert 1 <= sides["left"] <= 5 and 1 <= sides["right"] <= 5
        else:
            assert not sides
    assert all(pepper.color == "red" and pepper.ripe for pepper in scene.peppers)


def test_pepper_ids_are_unique_positive_and_mask_safe(paper):
    _, scene = paper
    ids = [pepper.id for pepper in scene.peppers]
    assert len(set(ids)) == len(ids)
    assert min(ids) >= 1 and max(ids) < 32768


def test_peppers_inside_their_plant_on_their_side_and_apart(paper):
    _, scene = paper
    for pepper in scene.peppers:
        plant = scene.plant(pepper.plant)
        assert plant.bounds.contains(pepper.center)
        offset = pepper.center[0] - plant.position[0]
        assert (offset < 0) == (pepper.side == "left")
        pot_top = plant.position[2] + plant.pot.height
        assert pepper.center[2] - pepper.radius > pot_top  # clear of the pot
        assert 0.07 <= pepper.length <= 0.10
    for a, b in itertools.combinations(scene.peppers, 2):
        assert np.linalg.norm(np.subtract(a.center, b.center)) >= a.radius + b.radius


def test_peppers_hang_from_the_stem(paper):
    _, scene = paper
    for pepper in scene.peppers:
        stem = np.array(scene.plant(pepper.plant).stem.points)
        stalk = np.array(pepper.peduncle.points)
        start_to_stem = np.min(np.linalg.norm(stem[:, :2] - stalk[0, :2], axis=1))
        assert start_to_stem < 0.02 and stem[0, 2] <= stalk[0, 2] <= stem[-1, 2]
        top = np.array(pepper.center) - np.array(pepper.axis) * pepper.length / 2
        assert np.allclose(stalk[-1], top, atol=1e-5)
        assert stalk[-2, 2] > top[2]  # the stalk comes down onto the fruit: it hangs


def test_meshes_stay_in_the_plant_bounds_and_pepper_spheres(demo):
    _, scene = demo
    for plant in scene.plants:
        parts = plant_meshes(plant, scene.peppers_of(plant.id))
        vertices = parts.all_vertices()
        assert np.all(vertices >= np.array(plant.bounds.min) - 1e-9)
        assert np.all(vertices <= np.array(plant.bounds.max) + 1e-9)
        assert len(parts.leaves) >= 10
        for pepper in scene.peppers_of(plant.id):
            distance = np.linalg.norm(parts.peppers[pepper.id].vertices - pepper.center, axis=1)
            assert distance.max() <= pepper.radius
            for leaf in parts.leaves:  # no leaf cuts into a fruit
                assert np.linalg.norm(leaf.vertices - pepper.center, axis=1).min() >= pepper.radius - 1e-6


def test_demo_has_mixed_ripeness_and_every_plant_bears(demo):
    _, scene = demo
    assert len(scene.plants) == 4 and all(plant.bearing for plant in scene.plants)
    assert {p.ripe for p in scene.peppers} == {True, False}
    assert all(p.ripe == (p.color != "green") for p in scene.peppers)


def test_too_many_peppers_for_the_plant_is_a_user_error():
    crowded = load_config("demo").override({"plants": {"peppers": {"per_side": (60, 60)}}})
    with pytest.raises(UserError, match="plants.peppers.per_side"):
        generate_scene(crowded)


def test_overlapping_tables_are_refused():
    overlapping = load_config("demo").override({"greenhouse": {"tables": [(1.0, 2.5), (1.2, 2.5)]}})
    with pytest.raises(UserError, match="tables 0 and 1 overlap"):
        generate_scene(overlapping)


def test_one_object_list_and_one_material_table_for_every_view(demo):
    """Both renderers draw `greenhouse_objects`, the physics world holds the same static shapes, and every
    colour comes from the one material table; the module needs neither Blender nor MuJoCo."""
    import subprocess
    import sys
    import xml.etree.ElementTree as ET

    from renderloop.scene.materials import MATERIALS, display_rgba
    from renderloop.scene.objects import collision_objects, greenhouse_objects, static_objects
    from renderloop.scene.world import world_xml

    config, scene = demo
    objects = greenhouse_objects(scene)
    assert all(MATERIALS[obj.material].recipe is not None for obj in objects)  # Cycles can draw each
    assert {obj.pass_index: obj.name for obj in objects if obj.pass_index} == {p.id: f"pepper_{p.id}" for p in scene.peppers}
    assert [obj.shapes for obj in collision_objects(scene)[:4]] == [obj.shapes for obj in static_objects(scene)]
    root = ET.fromstring(world_xml(scene, config))
    rgba = {m.get("name"): tuple(map(float, m.get("rgba").split())) for m in root.iter("material")}
    assert rgba and all(rgba[name] == display_rgba(name) for name in rgba)
    assert display_rgba("floor") == (*MATERIALS["floor"].base_rgb, 1.0)  # derived from the Cycles colour
    code = ("import sys, renderloop.scene.objects, renderloop.scene.materials; "
            "sys.exit(any(m in sys.modules for m in ('bpy', 'mujoco')))")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0
