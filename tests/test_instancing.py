"""Plants as copies of a library of prototypes: a long row costs a few plants' growth and a small scene.json,
while every copy's fruit stay its own and exact, and the presets grow as they did."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import platform
import subprocess
import sys

import numpy as np
import pytest

from renderloop.config import load_config
from renderloop.errors import UserError
from renderloop.io.atomic import dumps_json
from renderloop.scene.generate import generate_scene
from renderloop.scene.model import load_scene, placement, read_scene, write_scene
from renderloop.scene.objects import Group, expand_groups, greenhouse_objects
from renderloop.scene.plant_meshes import pepper_mesh, plant_meshes

# Taken from the code before plants could be copies of prototypes (same seeds): the sha1 of every plant's fruit count,
# ripe count and fruit (id, colour, centre to 0.1 mm), and the sha256 of the whole scene.json. The greenhouse's
# scene.json was taken again when a shoot's ties in distance became broken by their order (a stable sort): before, the
# high-wire plants' shoots depended on which SIMD instructions numpy's sort ran on.
PRESET_TRUTH = {
    ("paper", 0): ("807cbb3238d070b1e8770b3ae80ae1e5cb70dd23",
                   "6925152c810a5e62c171a3ada7360c1d82c60ca8ae92f9b55f0ce1fbef2ac74b"),
    ("paper", 7): ("f5bdb597ab4fe59e4c9745a2d0130be1c8bcb93b",
                   "5616403501789cacdeec7859051d4c15a7269192a674fca6d46a06838585e765"),
    ("demo", 0): ("1184ff498d5ab7c402736b359413e7dbd0749fc5",
                  "acf1ae00ca0e39bb92035d617b29d32e1cf1762841d85e3ebfa1136917b726fc"),
    ("demo", 3): ("2393b0bbca88bb6168b900f5d90dcd6ba4df13c5",
                  "9599cfdcdeab7280db7f87eca5efd18e8d2f54c41ab27151d59bbc3f871342bc"),
    ("greenhouse", 0): ("89ee7e6a2eaad156d787e43cb248fd0d4ec85894",
                        "6acc13979f63572f7fad0f88a4eb50a4ec217e9168c263fca08cec3e8b970cb6"),
}
# numpy 1.26's dispatched x86 extensions above its SSE3 baseline (`numpy.show_runtime()`), newest first as disabling
# them needs.
ABOVE_SSE3 = ("AVX512_SPR", "AVX512_ICL", "AVX512_CNL", "AVX512_CLX", "AVX512_KNM", "AVX512_KNL", "AVX512_SKX",
              "AVX512CD", "AVX512F", "AVX2", "FMA3", "F16C", "AVX", "SSE42", "POPCNT", "SSE41", "SSSE3")
SMALL_PEPPER = {"style": "pepper", "pepper_style": {"leaves": [20, 30]}, "bearing": None,
                "peppers": {"per_side": [1, 3], "colors": {"red": 0.4, "yellow": 0.2, "green": 0.4}}}


def fruit_truth(scene) -> str:
    rows = []
    for plant in scene.plants:
        fruit = scene.peppers_of(plant.id)
        rows.append([plant.id, len(fruit), sum(p.ripe for p in fruit),
                     [[p.id, p.color, [round(c, 4) for c in p.center]] for p in fruit]])
    return hashlib.sha1(json.dumps(rows).encode()).hexdigest()


def scene_bytes(scene) -> str:
    return dumps_json(scene.model_dump(mode="json"))


@functools.cache
def copied_scene(plants: int = 12, prototypes: int = 3, seed: int = 0, style: str = "pepper"):
    """One table of `plants` plants, copies of `prototypes` prototypes."""
    plants_config = {**SMALL_PEPPER, "prototypes": prototypes}
    if style != "pepper":
        plants_config = {"style": style, "prototypes": prototypes, "bearing": None}
    config = load_config("demo", seed=seed).override({
        "greenhouse": {"size": [4.0, plants * 0.5 + 4.0, 3.5], "table_size": [0.5, plants * 0.5, 0.6],
                       "tables": [[1.0, 0.5]], "plants_per_table": plants, "workstation_center": [-1.0, 0.0]},
        "plants": plants_config})
    return config, generate_scene(config)


@pytest.mark.parametrize("preset,seed", sorted(PRESET_TRUTH))
def test_the_presets_grow_the_same_fruit_and_the_same_scene_json_as_before_instancing(preset, seed):
    scene = generate_scene(load_config(preset, seed=seed))
    assert scene.prototypes is None and not any(plant.is_copy for plant in scene.plants)
    truth, whole = PRESET_TRUTH[(preset, seed)]
    assert fruit_truth(scene) == truth
    assert hashlib.sha256(scene_bytes(scene).encode()).hexdigest() == whole


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="names x86's SIMD extensions")
def test_the_greenhouse_grows_the_same_scene_json_whichever_simd_instructions_numpy_runs_on():
    # numpy picks its sort and its transcendental functions by the CPU it finds (AVX-512, AVX2, SSE): a scene must not
    # depend on which, or the same seed grows another greenhouse on another machine. Disabling what a CPU lacks is a
    # no-op, so on any x86 machine this compares what it has with the baseline.
    grow = ("import hashlib; from renderloop.config import load_config; from renderloop.io.atomic import dumps_json; "
            "from renderloop.scene.generate import generate_scene; "
            "scene = generate_scene(load_config('greenhouse', seed=0)); "
            "print(hashlib.sha256(dumps_json(scene.model_dump(mode='json')).encode()).hexdigest())")
    baseline = {**os.environ, "NPY_DISABLE_CPU_FEATURES": " ".join(ABOVE_SSE3)}
    digest = subprocess.run([sys.executable, "-c", grow], env=baseline, capture_output=True, text=True, check=True)
    assert digest.stdout.strip() == PRESET_TRUTH[("greenhouse", 0)][1]


def test_copies_share_their_prototypes_so_scene_json_grows_by_a_few_hundred_bytes_a_plant():
    _, small = copied_scene(8, 3)
    _, large = copied_scene(16, 3)
    assert len(large.prototypes) == 3 and all(plant.is_copy and not plant.leaves for plant in large.plants)
    assert large.prototypes == small.prototypes  # one library per seed and plant config
    without_fruit = [len(scene_bytes(scene.model_copy(update={"peppers": []}))) for scene in (small, large)]
    per_plant = (without_fruit[1] - without_fruit[0]) / 8
    assert per_plant < 500, per_plant  # a prototype is tens of kilobytes
    prototype_bytes = len(dumps_json(large.prototypes[0].model_dump(mode="json")))
    assert prototype_bytes > 20 * per_plant  # what the copies do not repeat
    fruit_bytes = (len(scene_bytes(large)) - without_fruit[1]) / len(large.peppers)
    assert fruit_bytes < 250, fruit_bytes  # a copy's fruit keeps its own draws, the rest is its site's


def test_each_copys_fruit_is_a_site_of_its_prototype_moved_by_the_copys_placement():
    _, scene = copied_scene(12, 3)
    ids = [pepper.id for pepper in scene.peppers]
    assert ids == list(range(1, len(ids) + 1))
    carried = {}
    for plant in scene.plants:
        prototype = scene.prototype_of(plant)
        transform = placement(plant, prototype.plant)
        assert plant.yaw in (0.0, round(np.pi, 6))
        fruit = scene.peppers_of(plant.id)
        assert [p.side for p in fruit].count("left") >= 1 and [p.side for p in fruit].count("right") >= 1
        for pepper in fruit:
            site = prototype.fruit[pepper.site]
            stalk = np.asarray(site.peduncle.points[-1])
            expected = transform[:3, :3] @ (stalk + pepper.scale * (np.asarray(site.center) - stalk)) + transform[:3, 3]
            assert np.allclose(pepper.center, expected, atol=1e-6)
            assert np.allclose(pepper.peduncle.points, np.asarray(site.peduncle.points) @ transform[:3, :3].T
                               + transform[:3, 3], atol=1e-6)
            assert 0.85 <= pepper.scale <= 1.0 and pepper.radius <= site.radius + 3e-6
            assert (pepper.center[0] < plant.position[0]) == (pepper.side == "left")
            assert plant.bounds.contains(pepper.center, margin=-pepper.radius + 1e-5)
        carried.setdefault(plant.prototype, set()).add(tuple(sorted(p.site for p in fruit)))
    # copies of one prototype carry different fruit: the count is not a prototype's count repeated
    assert any(len(sets) > 1 for sets in carried.values())
    assert len({p.color for p in scene.peppers}) > 1


def test_a_scene_of_copies_reads_back_as_the_scene_written(tmp_path):
    _, scene = copied_scene(12, 3)
    write_scene(tmp_path, scene)
    back = read_scene(tmp_path)
    assert back == scene
    assert [p.model_dump() for p in back.peppers] == [p.model_dump() for p in scene.peppers]
    assert scene_bytes(back) == (tmp_path / "scene.json").read_text()


@pytest.mark.parametrize("damage,named", [
    (lambda d: d["plants"][2].update(prototype=7), "plants.2.prototype"),
    (lambda d: d["peppers"][0].update(site=99), "site 99"),
    (lambda d: d["peppers"][0].update(plant=-1), "peppers.0"),
    (lambda d: d["plants"][1].update(stem=d["prototypes"][0]["plant"]["stem"]), "plants.1"),
])
def test_a_damaged_reference_to_a_prototype_is_one_line_naming_it(tmp_path, damage, named):
    _, scene = copied_scene(12, 3)
    data = scene.model_dump(mode="json")
    damage(data)
    (tmp_path / "scene.json").write_text(dumps_json(data))
    with pytest.raises(UserError) as error:
        load_scene(tmp_path / "scene.json")
    assert named in str(error.value) and "\n" not in str(error.value)


def test_the_views_stand_each_prototype_once_where_its_copies_stand():
    _, scene = copied_scene(12, 3)
    grouped = greenhouse_objects(scene, groups=True)
    groups = [item for item in grouped if isinstance(item, Group)]
    assert len(groups) == len({plant.prototype for plant in scene.plants})
    assert sum(len(group.transforms) for group in groups) == len(scene.plants)
    plain = greenhouse_objects(scene)
    assert not any(isinstance(item, Group) for item in plain)
    assert [obj.name for obj in plain] == [obj.name for obj in expand_groups(grouped)]
    pots = next(obj for obj in plain if obj.name == "pot_prototype_0")
    assert pots.instances.rigid and len(pots.instances.templates) == 1
    copy = next(plant for plant in scene.plants if plant.prototype == 0)
    body = scene.prototype_of(copy).plant
    transform = placement(copy, body)
    placed = pots.instances.templates[0].transformed(transform[:3, :3], transform[:3, 3])
    own = plant_meshes(copy, []).pot.vertices  # the pot is round: a half turn reorders its vertices
    assert np.allclose(np.unique(placed.vertices.round(5), axis=0), np.unique(own.round(5), axis=0), atol=2e-5)
    fruit = [obj for obj in plain if obj.pass_index]
    assert sorted(obj.pass_index for obj in fruit) == [p.id for p in scene.peppers]
    # grouped, the copies' fruit are their sites' meshes, each copy with its own id; drawn so, a fruit is the mesh
    # its record describes, which every other view builds from scene.json
    shared = [obj for obj in grouped if not isinstance(obj, Group) and obj.instances is not None
              and obj.instances.pass_index is not None]
    assert sum(len(obj.instances.pass_index) for obj in shared) == len(scene.peppers)
    assert sum(len(obj.instances.templates) for obj in shared[:1]) < len(scene.peppers)
    by_id = {obj.pass_index: obj for obj in fruit}
    for pepper in scene.peppers:
        assert np.abs(by_id[pepper.id].mesh.vertices - pepper_mesh(pepper).vertices).max() < 1e-5


def test_copies_in_the_physics_world_have_their_prototypes_strings(tmp_path):
    import mujoco

    from renderloop.scene.world import world_xml

    config, scene = copied_scene(8, 2, style="highwire")
    for plant in scene.plants:
        strings = scene.strings_of(plant)
        assert 2 <= len(strings) <= 4 and all(plant.bounds.contains(foot, margin=1e-5) for foot in strings)
    config = config.override({"greenhouse": {"environment": {"kind": "film"}}})
    film = generate_scene(config)
    model = mujoco.MjModel.from_xml_string(world_xml(film, config))
    names = [model.geom(k).name for k in range(model.ngeom)]
    assert sum(name.startswith(("canopy", "plant_")) for name in names) == 8
    strings = [name for name in names if name.startswith("string_") and not name.startswith("string_bg")]
    assert len(strings) == sum(len(scene.strings_of(plant)) for plant in film.plants)
    # the neighbouring rows stand copies of the scene's own prototypes, which scene.json then holds once
    assert film.environment.shared == 2 and film.environment.prototypes == film.prototypes
    write_scene(tmp_path, film)
    assert "prototypes" not in json.loads((tmp_path / "scene.json").read_text())["environment"]
    assert read_scene(tmp_path) == film


def test_cycles_draws_two_copies_of_one_prototype_from_one_set_of_meshes():
    import bpy

    from renderloop.render.camera import Intrinsics
    from renderloop.render.cycles import CyclesRenderer
    from renderloop.robot.kinematics import look_at

    config, scene = copied_scene(2, 1)
    config = config.override({"camera": {"width": 64, "height": 48}, "renderer": {"samples": 1, "denoise": False}})
    intrinsics = Intrinsics.from_config(config.camera)
    pepper = scene.peppers[-1]
    side = -1.0 if pepper.side == "left" else 1.0
    pose = look_at(np.array(pepper.center) + np.array([side * 0.5, 0.0, 0.05]), pepper.center)
    with CyclesRenderer(scene, config, intrinsics) as renderer:
        empties = [obj for obj in bpy.data.objects if obj.instance_type == "COLLECTION"]
        assert len(empties) == 2 and len({obj.instance_collection.name for obj in empties}) == 1
        collection = empties[0].instance_collection
        assert collection.name not in [c.name for c in bpy.context.scene.collection.children]
        # the prototype's leaves are one mesh, each vertex carrying its leaf's colour: a copy is a few objects to sync
        leaves = [obj for obj in collection.objects if obj.name.startswith("leaf_copies")]
        assert len(leaves) == 1
        colours = np.array([c.color[:3] for c in leaves[0].data.attributes["leaf_rgb"].data])
        assert len(np.unique(colours.round(5), axis=0)) == len({tuple(leaf.rgb) for leaf in scene.prototypes[0].plant.leaves})
        fruit = [obj for obj in bpy.data.objects if obj.pass_index > 0]
        assert sorted(obj.pass_index for obj in fruit) == [p.id for p in scene.peppers]
        assert len({obj.data.name for obj in fruit}) == len({p.site for p in scene.peppers})  # a site's mesh, shared
        frame = renderer.render(pose)
    assert pepper.id in frame.mask


def test_a_prototypes_leaves_look_in_cycles_as_the_same_leaves_drawn_one_object_each():
    # the leaves of a prototype instanced by its copies read colour and dust from their vertices; drawn one object a
    # leaf outside the prototype they read them from their objects: the two frames agree to sampling noise
    from renderloop.render.camera import Intrinsics
    from renderloop.render.cycles import CyclesRenderer
    from renderloop.robot.kinematics import look_at
    from renderloop.scene.objects import SceneObject

    config, scene = copied_scene(2, 1)
    config = config.override({"camera": {"width": 48, "height": 64}, "renderer": {"samples": 4, "denoise": False}})
    group = next(item for item in greenhouse_objects(scene, groups=True) if isinstance(item, Group))
    moved = group.transforms[0]
    leaves = next(obj for obj in group.objects if obj.instances is not None)
    placed = SceneObject(leaves.name, material=leaves.material, smooth=True, instances=dataclasses.replace(
        leaves.instances, transforms=moved @ leaves.instances.transforms))
    centre = placed.triangles().vertices.mean(axis=0)
    pose = look_at(centre + [0.4, 0.0, 0.05], centre)
    intrinsics = Intrinsics.from_config(config.camera)
    frames = []
    for objects in ([Group(group.name, (leaves,), group.transforms[:1])], [placed]):
        with CyclesRenderer.from_objects(objects, config, intrinsics, seed=scene.seed) as renderer:
            frames.append(renderer.render(pose))
    grouped, own = frames
    seen = own.depth > 0  # the leaves, not the sky behind them
    assert seen.mean() > 0.1 and np.array_equal(seen, grouped.depth > 0)
    colours = [frame.rgb[seen].astype(float).mean(axis=0) for frame in frames]
    assert np.abs(colours[0] - colours[1]).max() < 4.0  # a copy's own colour and dust, not its instancer's white


def test_a_compartment_the_machine_cannot_hold_is_refused_in_one_line_before_anything_is_written(
        tmp_path, monkeypatch, capsys):
    from renderloop.scene import capacity
    from tests.conftest import cli

    config = load_config("commercial")
    need = capacity.estimate(config)
    assert need.plants == 208 and need.grown == 24 and need.memory < 1e9
    larger = capacity.estimate(config.override({"plants": {"prototypes": 208}}))
    assert larger.memory > 2 * need.memory and larger.disk > 2 * need.disk  # grown in place, not copies
    with pytest.raises(UserError, match=r"208 plants \(24 grown.*GB of memory.*0.10 GB available"):
        capacity.check_capacity(config, tmp_path, memory=1e8)
    with pytest.raises(UserError, match=r"MB of disk, but 1 MB are free"):
        capacity.check_capacity(config, tmp_path, memory=1e12, disk=1e6)
    monkeypatch.setattr(capacity, "available_memory", lambda: 1e8)
    code, _, err = cli(monkeypatch, capsys, "scene", "--preset", "commercial", "--out", str(tmp_path / "run"))
    assert code != 0 and "GB of memory" in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "run").exists()
