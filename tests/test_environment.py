"""The 'film' greenhouse environment: opt-in, the default renders as before, its neighbouring rows' fruit marked apart
in the masks,
its structure clear of the scan, and the greenhouse preset runs end to end."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from conftest import cli
from renderloop.config import Config, load_config
from renderloop.planning.stage import run_plan
from renderloop.planning.waypoints import plan_waypoints
from renderloop.render.camera import Intrinsics
from renderloop.robot.kinematics import look_at
from renderloop.rundir import names
from renderloop.scene.generate import generate_scene
from renderloop.scene.model import NEIGHBOUR_FRUIT_ID, Scene, read_scene
from renderloop.scene.objects import collision_objects, greenhouse_objects
from renderloop.scene.stage import run_scene
from renderloop.scene.world import world_xml

# sha256 of the demo world (seed 0): the geoms the code before the environment existed wrote (2026-11-23), with the
# floor and each wall in a static body of its own since 2026-11-26 (the only difference, checked by diff); its
# scene.json is pinned by tests/test_pepper_style.py.
PLAIN_WORLD_SHA256 = "91fdbe99c87c598b1a7f81c66409d4aca90b7e1a293978909a1699c644c6c358"
LEAN = {"plants": {"pepper_style": {"leaves": [30, 40]}}}  # the greenhouse preset with few leaves: seconds, not minutes


def config_of(preset: str, **overrides: dict) -> Config:
    return load_config(preset).override(overrides)


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def side_pose(plant) -> np.ndarray:
    target = np.array([plant.position[0], plant.position[1], plant.bounds.max[2] - 0.2])
    return look_at(target + np.array([-0.45, -0.1, 0.05]), target)


def test_the_plain_environment_is_the_default_and_builds_the_same_world_as_before():
    config = config_of("demo")
    assert config.greenhouse.environment.kind == "plain"
    scene = generate_scene(config)
    assert scene.environment is None and "environment" not in scene.model_dump(mode="json")
    assert sha256(world_xml(scene, config).encode()) == PLAIN_WORLD_SHA256


@pytest.fixture(scope="module")
def film():
    config = config_of("greenhouse", **LEAN, camera={"width": 160, "height": 120})
    return config, generate_scene(config)


@pytest.fixture(scope="module")
def plain() -> Scene:
    return generate_scene(config_of("greenhouse", **LEAN, greenhouse={"environment": {"kind": "plain"}}))


def test_a_film_scene_grows_the_same_scanned_plants_and_stands_its_neighbouring_rows_outside_the_room(film, plain):
    config, scene = film
    assert scene.plants == plain.plants and scene.peppers == plain.peppers  # the environment draws from its own stream
    environment = scene.environment
    assert environment is not None and len(environment.plants) > 50 and environment.traps
    length, width, _ = scene.room
    for copy in environment.plants:
        bounds = environment.prototypes[copy.prototype].plant.bounds
        reach = np.hypot(*np.maximum(np.abs(bounds.min[:2]), np.abs(bounds.max[:2])))
        assert abs(copy.position[0]) - reach > length / 2 or abs(copy.position[1]) - reach > width / 2
    objects = greenhouse_objects(scene)
    assert {obj.pass_index for obj in objects if obj.pass_index} == {pepper.id for pepper in scene.peppers} | {NEIGHBOUR_FRUIT_ID}
    background = [obj for obj in objects if obj.name.startswith("background_")]
    assert any(obj.name.startswith("background_fruit") for obj in background)  # the neighbours bear fruit, unlabelled
    assert all((obj.pass_index == NEIGHBOUR_FRUIT_ID) == obj.name.startswith("background_fruit") for obj in background)


def test_the_neighbouring_rows_fruit_and_only_they_have_the_neighbour_id_and_the_rest_of_the_rows_id_0(film):
    """A raster frame from the aisle, looking across the scanned row at the next row: fruit beyond the room are in
    view and marked NEIGHBOUR_FRUIT_ID, every other pixel beyond the room is 0, and every pepper id lies on its
    scanned pepper."""
    from renderloop.render.raster import RasterRenderer

    config, scene = film
    intrinsics = Intrinsics.from_config(config.camera)
    plant = scene.plants[2]
    eye = np.array([-1.0, plant.position[1], 1.0])
    pose = look_at(eye, eye + np.array([1.0, 0.0, -0.05]))
    with RasterRenderer(scene, config, intrinsics) as raster:
        frame = raster.render(pose)
    rows, cols = np.nonzero(frame.depth > 0)
    points = intrinsics.back_project(np.column_stack([cols, rows]), frame.depth[rows, cols]) @ pose[:3, :3].T + pose[:3, 3]
    beyond = points[:, 0] > scene.room[0] / 2
    rgb = frame.rgb[rows, cols].astype(int)
    fruity = (rgb[:, 0] > 120) & (rgb[:, 0] > rgb[:, 1] + 40) & (rgb[:, 2] < 90)  # red, orange or yellow skin
    assert beyond.sum() > 1000 and (beyond & fruity).sum() > 10  # the next row and some of its fruit are in view
    ids = frame.mask[rows, cols]
    neighbour = ids == NEIGHBOUR_FRUIT_ID
    assert np.all(beyond[neighbour]) and set(np.unique(ids[beyond]).tolist()) == {0, NEIGHBOUR_FRUIT_ID}
    assert (neighbour & fruity).sum() >= 0.8 * (beyond & fruity).sum()
    for pepper in scene.peppers:
        on = ids == pepper.id
        if on.any():
            assert np.linalg.norm(points[on] - pepper.center, axis=1).max() <= 1.5 * pepper.radius


def test_the_greenhouse_scan_keeps_the_planners_clearance_and_is_the_plain_scan(tmp_path: Path, plain):
    """`renderloop plan` checks the trajectory against world.xml with the planner's clearance: the strings over the
    scanned plants are in it. The scan is the one planned without the film greenhouse."""
    config = config_of("greenhouse", **LEAN)
    run_scene(tmp_path, config)
    run_plan(tmp_path, config)
    scene = read_scene(tmp_path)
    strings = [shape for obj in collision_objects(scene) if obj.name == "wires" for shape in obj.shapes]
    assert len(strings) >= len(scene.plants)
    world = (tmp_path / names.WORLD).read_text()
    assert all(f'name="{shape.name}"' in world for shape in strings)
    planned = np.array([waypoint.dofs for waypoint in plan_waypoints(scene, config)])
    assert np.array_equal(planned, np.array([waypoint.dofs for waypoint in plan_waypoints(plain, config)]))


def test_renderloop_run_with_the_greenhouse_preset_completes(monkeypatch, capsys, tmp_path: Path):
    tiny = tmp_path / "tiny.yaml"
    tiny.write_text("renderer: {backend: raster}\ncamera: {width: 64, height: 48, rate_hz: 0.05}\n"
                    "plants: {pepper_style: {leaves: [20, 30]}}\n")
    code, _, err = cli(monkeypatch, capsys, "run", "--preset", "greenhouse", "--config", str(tiny), "--out", str(tmp_path / "gh"))
    assert code == 0, err
    assert (tmp_path / "gh" / names.COUNTS).is_file() and (tmp_path / "gh" / "report.html").is_file()
    assert read_scene(tmp_path / "gh").environment is not None
    # its frames as a training set: the neighbouring rows' fruit labelled too, told apart by the depth frames
    from renderloop.dataset.build import image_name
    from renderloop.dataset.from_runs import dataset_from_runs
    from renderloop.render.frames import read_png

    images = dataset_from_runs([tmp_path / "gh"], tmp_path / "set", val_runs=0)
    marked = labelled = 0
    for index in range(images):
        record = json.loads((tmp_path / "set" / "labels" / image_name(index, "json")).read_text())
        mask = read_png(tmp_path / "gh" / names.frame_file(names.MASKS, record["frame"]), np.uint16)
        marked += int((mask == NEIGHBOUR_FRUIT_ID).sum())
        labelled += sum(p["pixels"] for p in record["peppers"] if p["pepper_id"] is None)
    assert marked > 0 and labelled >= 0.99 * marked


def test_a_cycles_frame_of_the_film_greenhouse_shows_the_crop_against_clipped_white_film(film):
    from renderloop.render.cycles import CyclesRenderer

    scene = film[1]
    config = config_of("greenhouse", **LEAN, camera={"width": 80, "height": 60})
    intrinsics = Intrinsics.from_config(config.camera)
    with CyclesRenderer(scene, config, intrinsics) as cycles:
        frame = cycles.render(side_pose(scene.plants[1]))
        assert cycles.lighting["exposure"] > 0
    far = frame.depth == 0  # beyond the clip range: the film far off, as an auto-exposed camera clips it
    assert far.sum() > 50 and np.median(frame.rgb[far].min(axis=1)) >= 240
    near = frame.rgb[~far].astype(float)
    assert 40 < near.mean() < 200  # the crop exposed, neither black nor blown out
    assert set(np.unique(frame.mask)) <= {0, NEIGHBOUR_FRUIT_ID} | {pepper.id for pepper in scene.peppers}
