"""The 'pepper' plant style: dense plants whose fruit hang from nodes, while the default style stays as it was."""

from __future__ import annotations

import hashlib
import itertools

import numpy as np
import pytest

from renderloop.config import Config, load_config
from renderloop.io.atomic import dumps_json
from renderloop.scene.generate import generate_scene
from renderloop.scene.model import Scene
from renderloop.scene.objects import greenhouse_objects
from renderloop.scene.pepper_plant import LEAF_RGB
from renderloop.scene.plant_meshes import LEAF_SHAPES, plant_meshes

# sha256 of scene.json written by the code before the 'pepper' style existed (2026-11-23), same seeds.
SIMPLE_SCENE_SHA256 = {
    ("demo", 0): "acf1ae00ca0e39bb92035d617b29d32e1cf1762841d85e3ebfa1136917b726fc",
    ("paper", 7): "5616403501789cacdeec7859051d4c15a7269192a674fca6d46a06838585e765",
}


def pepper_config(preset: str = "demo", seed: int = 0, **camera) -> Config:
    return load_config(preset, seed=seed).override({"plants": {"style": "pepper"}, "camera": camera})


@pytest.fixture(scope="module")
def pepper_scene():
    config = pepper_config()
    return config, generate_scene(config)


def _sha256(scene) -> str:
    return hashlib.sha256(dumps_json(scene.model_dump(mode="json")).encode()).hexdigest()


def test_the_default_style_writes_the_same_scene_json_as_before(demo, paper):
    assert load_config("demo").plants.style == "simple"
    assert _sha256(demo[1]) == SIMPLE_SCENE_SHA256[("demo", 0)]
    assert _sha256(paper[1]) == SIMPLE_SCENE_SHA256[("paper", 7)]


def test_one_seed_gives_the_same_fruit_in_both_styles_and_the_same_bytes_twice(demo, pepper_scene):
    config, scene = pepper_scene
    assert _sha256(generate_scene(config)) == _sha256(scene)
    assert Scene.model_validate_json(dumps_json(scene.model_dump(mode="json"))) == scene  # the file reads back
    fields = ("id", "plant", "side", "center", "radius", "color", "ripe", "rgb", "length", "width", "axis")
    assert [[getattr(p, f) for f in fields] for p in scene.peppers] == [[getattr(p, f) for f in fields] for p in demo[1].peppers]


def test_pepper_plants_have_60_to_200_leaves_of_6_to_20_cm_inside_their_box(pepper_scene):
    _, scene = pepper_scene
    for plant in scene.plants:
        assert 60 <= len(plant.leaves) <= 200
        assert all(0.06 <= leaf.length <= 0.20 and leaf.template is not None for leaf in plant.leaves)
        assert len({leaf.template for leaf in plant.leaves}) <= len(LEAF_SHAPES)
        parts = plant_meshes(plant, scene.peppers_of(plant.id))
        vertices = parts.all_vertices()
        assert np.all(vertices >= np.array(plant.bounds.min) - 1e-9)
        assert np.all(vertices <= np.array(plant.bounds.max) + 1e-9)
        for pepper in scene.peppers_of(plant.id):
            assert np.linalg.norm(parts.peppers[pepper.id].vertices - pepper.center, axis=1).max() <= pepper.radius
            for leaf in parts.leaves:  # no leaf cuts into a fruit
                assert np.linalg.norm(leaf.vertices - pepper.center, axis=1).min() >= pepper.radius - 1e-6
    leaves = [leaf for plant in scene.plants for leaf in plant.leaves]
    assert any(leaf.template >= 8 for leaf in leaves) and any(leaf.dust for leaf in leaves)  # a few damaged, a few dusty


def test_a_leaf_tint_lightens_each_plants_leaves_towards_yellow_green_and_moves_no_leaf(pepper_scene):
    config, scene = pepper_scene
    tinted = generate_scene(config.override({"plants": {"pepper_style": {"leaf_tint": [0.0, 1.0]}}}))
    shape = ("base", "direction", "up", "length", "width", "template", "dust")
    tints = []
    for plain, light in zip(scene.plants, tinted.plants):
        assert [[getattr(leaf, f) for f in shape] for leaf in plain.leaves] == [[getattr(leaf, f) for f in shape] for leaf in light.leaves]
        before, after = (np.array([leaf.rgb for leaf in plant.leaves]) for plant in (plain, light))
        # each plant is tinted as a whole: every leaf's red rises over its green by one factor for its plant
        ratio = (after[:, 0] / after[:, 1]) / (before[:, 0] / before[:, 1])
        healthy = np.abs(before[:, 0] / before[:, 1] - LEAF_RGB[0] / LEAF_RGB[1]) < 0.3  # not yellowed
        tints.append(np.median(ratio[healthy]))
        assert np.all(ratio[healthy] >= 1.0 - 1e-6)
    assert max(tints) > 1.3 and max(tints) - min(tints) > 0.1  # drawn per plant: some far, some near


def test_every_fruit_hangs_from_a_node_by_a_peduncle_and_has_a_calyx(pepper_scene):
    _, scene = pepper_scene
    for pepper in scene.peppers:
        plant = scene.plant(pepper.plant)
        polylines = [np.array(tube.points) for tube in (plant.stem, *plant.branches)]
        node = np.array(pepper.peduncle.points[0])
        # a node: a vertex where a shoot goes on, inside a polyline or where one ends and another starts
        meets = sum(int(np.any(np.linalg.norm(line[1:-1] - node, axis=1) < 1e-6)) * 2
                    + int(np.linalg.norm(line[0] - node) < 1e-6) + int(np.linalg.norm(line[-1] - node) < 1e-6)
                    for line in polylines)
        assert meets >= 2, f"pepper {pepper.id}: its peduncle starts at {node}, not at a node"
        top = np.array(pepper.center) - np.array(pepper.axis) * pepper.length / 2
        stalk = np.array(pepper.peduncle.points)
        assert np.allclose(stalk[-1], top, atol=1e-5)
        assert node[2] > top[2] and stalk[-2] @ pepper.axis < top @ pepper.axis  # it comes down onto the fruit: it hangs
        assert pepper.calyx is not None and 5 <= pepper.calyx.sepals <= 7
        assert 0.15 * pepper.width <= pepper.calyx.reach <= 0.3 * pepper.width
        assert pepper.ripeness is not None and (pepper.ripeness == 1.0 or pepper.color != "green")
    calyces = {plant.id: plant_meshes(plant, scene.peppers_of(plant.id)).calyces for plant in scene.plants}
    for plant in scene.plants:
        for pepper in scene.peppers_of(plant.id):  # some calyx vertex sits on each fruit's stalk end
            top = np.array(pepper.center) - np.array(pepper.axis) * pepper.length / 2
            assert np.linalg.norm(calyces[plant.id].vertices - top, axis=1).min() < 0.005
    assert {p.ripeness == 1.0 for p in scene.peppers if p.ripe} == {True, False}  # some are still turning


def test_the_fruit_stay_apart_and_the_leaves_are_copies_of_the_templates(pepper_scene):
    _, scene = pepper_scene
    for a, b in itertools.combinations(scene.peppers, 2):
        assert np.linalg.norm(np.subtract(a.center, b.center)) >= a.radius + b.radius
    objects = {obj.name: obj for obj in greenhouse_objects(scene)}
    plant = scene.plants[0]
    copies = objects[f"leaf_copies_{plant.id}"]
    assert copies.mesh is None and len(copies.instances.template) == len(plant.leaves)
    merged = copies.triangles()
    expected = np.vstack([m.vertices for m in plant_meshes(plant, scene.peppers_of(plant.id)).leaves])
    assert np.allclose(merged.vertices, expected)  # the raster view draws exactly the copies Cycles instances
    assert f"leaves_{plant.id}" not in objects and f"calyces_{plant.id}" in objects


def test_a_leaf_template_is_a_clean_ovate_blade_facing_up_and_damage_takes_faces_away():
    from renderloop.scene.meshes import PEPPER_LEAF_WIDTH
    from renderloop.scene.plant_meshes import HEALTHY_SHAPES, PETIOLE, leaf_template

    for index in range(len(LEAF_SHAPES)):
        blade = leaf_template(index)
        normals = blade.face_normals()
        assert 0.5 * np.linalg.norm(normals, axis=1).min() > 1e-8  # no degenerate triangle
        assert np.all(blade.uv >= 0) and np.all(blade.uv <= 1)
        assert np.mean(normals[:, 2] > 0) > 0.9  # the upper side faces +z
        assert np.ptp(blade.vertices[:, 1]) == pytest.approx(PEPPER_LEAF_WIDTH, rel=0.1)
        midrib = blade.vertices[blade.uv[:, 1] == 0.5]  # petiole base to tip, in order
        assert np.allclose(midrib[0], 0.0, atol=0.01) and midrib[-1, 2] < midrib[:, 2].max()  # it droops
        assert np.linalg.norm(np.diff(midrib, axis=0), axis=1).sum() == pytest.approx(1.0 + PETIOLE)
    whole = len(leaf_template(0).faces)
    assert all(len(leaf_template(i).faces) == whole for i in range(HEALTHY_SHAPES))
    assert all(len(leaf_template(i).faces) < whole for i in range(HEALTHY_SHAPES, len(LEAF_SHAPES)))


def test_a_calyx_lies_on_the_stalk_end_facing_away_from_the_fruit_inside_its_sphere():
    from renderloop.scene import meshes

    center, axis = np.array([0.2, -0.1, 1.0]), np.array([0.2, 0.1, -1.0]) / np.linalg.norm([0.2, 0.1, -1.0])
    fruit = meshes.pepper(center, axis, 0.09, 0.08, 4, 0.1, twist=0.4)
    bound = np.linalg.norm(fruit.vertices - center, axis=1).max()
    cap = meshes.calyx(center, axis, 0.09, 0.08, 4, 0.1, 0.4, 6, 0.02, bound)
    top = center - axis * 0.045
    assert np.linalg.norm(cap.vertices - center, axis=1).max() <= bound + 1e-12
    assert np.linalg.norm(cap.vertices - top, axis=1).max() < 0.03
    faces = cap.vertices[cap.faces].mean(axis=1)
    normals = cap.face_normals()
    assert np.mean(np.einsum("ij,ij->i", normals, faces - center) > 0) > 0.95  # away from the fruit
    nearest = np.array([np.linalg.norm(fruit.vertices - v, axis=1).min() for v in cap.vertices])
    assert nearest.max() < 0.01  # on the skin, not floating


def test_a_cycles_render_of_a_pepper_plant_shows_every_fruit_from_its_side():
    """Cycles, 160x120 at one sample: each fruit of a plant is in the mask seen from its side of the row, and
    the Blender scene holds a few leaf meshes for hundreds of leaves (instances)."""
    import bpy

    from renderloop.render.camera import Intrinsics
    from renderloop.render.cycles import CyclesRenderer
    from renderloop.robot.kinematics import look_at

    config = pepper_config(width=160, height=120).override({"renderer": {"samples": 1, "denoise": False}})
    scene = generate_scene(config)
    plant = scene.plants[1]
    high = np.array(plant.bounds.max)
    target = np.array([plant.position[0], plant.position[1], (plant.position[2] + plant.pot.height + high[2]) / 2])
    with CyclesRenderer(scene, config, Intrinsics.from_config(config.camera)) as renderer:
        leaves = sum(len(p.leaves) for p in scene.plants)
        assert len(bpy.data.meshes) < len(bpy.data.objects) and len(bpy.data.meshes) < 100 < leaves
        for side, sign in (("left", -1.0), ("right", 1.0)):
            frame = renderer.render(look_at(target + np.array([sign * 0.75, 0.0, 0.05]), target))
            for pepper in (p for p in scene.peppers_of(plant.id) if p.side == side):
                assert np.count_nonzero(frame.mask == pepper.id) >= 4, f"pepper {pepper.id} ({side}) is not in view"
