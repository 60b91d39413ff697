"""The training set's realism: both plant styles and surroundings, clutter that is not a pepper, close views."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from renderloop.dataset.build import build_dataset
from renderloop.dataset.clutter import PEPPER_CLEARANCE, clutter_objects, standing_boards
from renderloop.dataset.picked import CRATE_WALL, picked_fruit
from renderloop.config.dataset import DatasetSpec
from renderloop.dataset.scenes import HIGHWIRE_HEIGHT, dataset_scene
from renderloop.dataset.views import CLOSE_DISTANCE, _through, close_view, picked_view, random_view
from renderloop.errors import UserError
from renderloop.render.camera import Intrinsics
from renderloop.scene.model import MAX_PEPPER_ID
from renderloop.scene.objects import Box
from renderloop.scene.plant_meshes import pepper_mesh

REAL = DatasetSpec(seed=21, styles=("simple", "pepper"), environments=("plain", "film"), clutter=True, close=0.5, sensor=0.5)


def test_scenes_draw_both_plant_styles_and_both_surroundings_and_the_neighbours_bear_fruit():
    drawn = [dataset_scene(REAL, index) for index in range(6)]
    assert {config.plants.style for config, _ in drawn} == {"simple", "pepper"}
    assert {config.greenhouse.environment.kind for config, _ in drawn} == {"plain", "film"}
    for config, scene in drawn:
        assert (scene.environment is not None) == (config.greenhouse.environment.kind == "film")
        if scene.environment is not None:
            assert scene.environment.prototypes and any(p.fruit for p in scene.environment.prototypes)  # labelled too
        assert config.camera.clip[0] == pytest.approx(0.05)  # close views need a near clip closer than the scan's
    # a spec that draws nothing new builds the scenes it always did
    plain = dataset_scene(DatasetSpec(seed=21), 0)
    assert plain[0].plants.style == "simple" and plain[1].environment is None and plain[0].camera.clip[0] == 0.2


def test_a_highwire_scene_stands_tall_plants_on_strings_on_a_low_gutter_and_views_reach_up_its_canopy():
    spec = DatasetSpec(seed=5, styles=("highwire",), environments=("film",))
    config, scene = dataset_scene(spec, 0)
    low, high = HIGHWIRE_HEIGHT
    assert config.plants.style == "highwire" and low <= config.plants.volume[2] <= high
    assert all(row.table.size[2] == pytest.approx(0.1) for row in scene.rows)
    assert all(plant.strings for plant in scene.plants)
    assert all(p.plant.strings for p in scene.environment.prototypes)  # the neighbours are the same crop
    rng = np.random.default_rng(0)
    heights = np.array([random_view(scene, rng)[2, 3] for _ in range(60)])
    canopy = [(p.position[2] + p.pot.height, p.bounds.max[2]) for p in scene.plants][0]
    assert heights.min() < canopy[0] + 0.3 * (canopy[1] - canopy[0]) and heights.max() > canopy[1] - 0.3 * (canopy[1] - canopy[0])


def test_clutter_keeps_clear_of_every_pepper_and_carries_no_instance_id():
    _, scene = dataset_scene(DatasetSpec(seed=4), 1)
    centres, radii = np.array([p.center for p in scene.peppers]), np.array([p.radius for p in scene.peppers])
    for seed in range(3):
        rng = np.random.default_rng(seed)
        boards = standing_boards(scene, rng)
        objects = clutter_objects(scene, rng, boards)
        assert len(objects) >= 7 and all(o.pass_index == 0 and o.material.startswith("clutter_") for o in objects)
        for thing in (o for o in objects if o.name.startswith("clutter_") and o.name[8:].isdigit()):
            vertices = thing.mesh.vertices
            gap = np.linalg.norm(vertices[:, None, :] - centres[None], axis=2).min(axis=0) - radii
            assert gap.min() > PEPPER_CLEARANCE - 1e-9
        for board in boards:
            low, high = np.asarray(board.center) - board.half, np.asarray(board.center) + board.half
            for plant in scene.plants:
                apart = (low > np.asarray(plant.bounds.max)) | (high < np.asarray(plant.bounds.min))
                assert apart.any()


def test_a_segment_through_a_box_meets_it_and_one_beside_it_does_not():
    board = Box("board", (0.0, 0.0, 1.0), (0.01, 0.5, 0.5))
    assert _through(np.array([-1.0, 0.0, 1.0]), np.array([1.0, 0.2, 1.2]), board)
    assert not _through(np.array([-1.0, 0.0, 1.0]), np.array([-0.5, 0.0, 1.0]), board)  # ends before it
    assert not _through(np.array([-1.0, 0.8, 1.0]), np.array([1.0, 0.8, 1.0]), board)  # passes beside it
    assert _through(np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.1, 1.0]), board)  # starts inside


def test_close_views_look_at_a_fruit_from_a_hands_breadth_to_half_a_metre_never_through_a_board_or_cutting_one():
    config, scene = dataset_scene(DatasetSpec(seed=4, close=1.0), 1)
    rng = np.random.default_rng(7)
    boards = standing_boards(scene, np.random.default_rng(3)) + [Box("wall", (-1.0, 0.0, 1.0), (0.01, 3.0, 1.0))]
    centres, radii = np.array([p.center for p in scene.peppers]), np.array([p.radius for p in scene.peppers])
    reach = Intrinsics.from_config(config.camera).corner_range(config.camera.clip[0])
    assert 1.1 * config.camera.clip[0] < reach < 1.3 * config.camera.clip[0]  # 57 degrees wide, 4:3
    for _ in range(200):  # 2 % of them cut a fruit when the clip's reach is not kept clear
        pose = close_view(scene, rng, boards, reach)
        camera = pose[:3, 3]
        # no fruit reaches the near clip plane, which would cut it open (its inside rendered black)
        assert np.all(np.linalg.norm(centres - camera, axis=1) >= radii + reach)
        local = (centres - camera) @ pose[:3, :3]  # the fruit in the optical frame
        near = np.linalg.norm(centres - camera, axis=1)
        ahead = np.abs(local[:, :2]).max(axis=1) < 0.5 * local[:, 2]  # within about 27 degrees of the optical axis
        looked_at = np.flatnonzero(ahead & (near >= CLOSE_DISTANCE[0] - 1e-9) & (near <= CLOSE_DISTANCE[1] + 1e-9))
        assert looked_at.size
        assert any(not any(_through(camera, centres[k], board) for board in boards) for k in looked_at)
    for _ in range(50):
        camera = random_view(scene, rng, obstacles=boards)[:3, 3]
        assert not any(_through(camera, camera, board) for board in boards)  # a point segment: inside the board


def _boxes_apart(a: Box, b: Box) -> bool:
    return bool(np.any(np.abs(np.asarray(a.center) - b.center) >= np.asarray(a.half) + b.half))


def test_picked_fruit_lie_every_way_up_in_crates_and_on_the_workstation_clear_of_each_other_and_the_plants():
    axes, counts = [], []
    for index in range(6):
        config, scene = dataset_scene(DatasetSpec(seed=4, styles=("pepper",), picked=1.0), index)
        boards = standing_boards(scene, np.random.default_rng(index))
        picked = picked_fruit(scene, np.random.default_rng(index), config.plants.peppers, boards)
        fruit = picked.fruit
        ids = [p.id for p in fruit]
        assert len(set(ids)) == len(ids) and min(ids) > max(p.id for p in scene.peppers) and max(ids) <= MAX_PEPPER_ID
        centres, radii = np.array([p.center for p in fruit]), np.array([p.radius for p in fruit])
        apart = np.linalg.norm(centres[:, None] - centres[None], axis=2) - radii[:, None] - radii[None]
        assert apart[~np.eye(len(fruit), dtype=bool)].min() > 0  # no two fruit meet
        solid = [Box("table", r.table.center, tuple(np.asarray(r.table.size) / 2)) for r in scene.rows] + boards
        solid += [Box("plant", tuple((np.asarray(p.bounds.min) + p.bounds.max) / 2),
                      tuple((np.asarray(p.bounds.max) - p.bounds.min) / 2)) for p in scene.plants]
        room = np.array(scene.room[:2]) / 2
        for crate in picked.crates:
            assert all(_boxes_apart(crate, other) for other in solid)
            assert np.all(np.abs(crate.center[:2]) + crate.half[:2] <= room)
        top = scene.workstation.center[2] + scene.workstation.size[2] / 2
        for pepper in fruit:  # on a crate's floor, on a fruit in it, or lying on the workstation's top
            lowest = pepper_mesh(pepper).vertices[:, 2].min()
            crate = next((c for c in picked.crates if np.all(np.abs(np.asarray(pepper.center[:2]) - c.center[:2])
                                                              < np.asarray(c.half[:2]) - CRATE_WALL)), None)
            if crate is None:
                assert lowest == pytest.approx(top, abs=1e-6)
            else:
                assert lowest >= crate.center[2] - crate.half[2] + CRATE_WALL - 1e-6
        axes += [p.axis for p in fruit]
        counts.append(len(fruit))
    assert min(counts) >= 1
    upright = np.abs(np.array(axes)[:, 2])
    assert (upright < 0.3).mean() > 0.2 and (upright > 0.7).mean() > 0.1  # on their sides, and stalk up or down


def test_views_of_picked_fruit_look_down_at_one_from_outside_every_crate_and_keep_the_clip_clear():
    config, scene = dataset_scene(DatasetSpec(seed=4, close=1.0, picked=1.0), 2)
    boards = standing_boards(scene, np.random.default_rng(2))
    picked = picked_fruit(scene, np.random.default_rng(2), config.plants.peppers, boards)
    reach = Intrinsics.from_config(config.camera).corner_range(config.camera.clip[0])
    every = [*scene.peppers, *picked.fruit]
    centres, radii = np.array([p.center for p in every]), np.array([p.radius for p in every])
    mine = np.array([p.center for p in picked.fruit])
    rng = np.random.default_rng(9)
    for _ in range(100):
        pose = picked_view(scene, picked.fruit, rng, boards, picked.crates, reach)
        camera = pose[:3, 3]
        assert not any(_through(camera, camera, box) for box in [*boards, *picked.crates])
        assert np.all(np.linalg.norm(centres - camera, axis=1) >= radii + reach)
        local = (mine - camera) @ pose[:3, :3]
        near = np.linalg.norm(mine - camera, axis=1)
        assert np.any((np.abs(local[:, :2]).max(axis=1) < 0.5 * local[:, 2]) & (near <= CLOSE_DISTANCE[1] + 1e-9)
                      & (mine[:, 2] < camera[2]))  # a picked fruit ahead, below the camera


def test_a_cluttered_dataset_of_close_views_labels_peppers_and_picked_fruit_only(tmp_path: Path):
    spec = REAL.model_copy(update=dict(width=64, height=48, views_per_scene=4, samples=(1,), val_every=2,
                               styles=("pepper",), environments=("plain",), close=1.0, picked=1.0))
    assert build_dataset(tmp_path, 4, spec) == 4
    _, scene = dataset_scene(spec, 0)
    ids = {pepper.id for pepper in scene.peppers}
    seen = set()
    for index in range(4):
        record = json.loads((tmp_path / "labels" / f"{index:06d}.json").read_text())
        seen |= {p["pepper_id"] for p in record["peppers"]}
        assert all(p["label"] in ("ripe", "unripe") for p in record["peppers"])
    assert seen & ids and seen - ids and min(seen - ids) > max(ids)  # the plants' fruit and picked ones above them
    coco = json.loads((tmp_path / "annotations" / "instances_train.json").read_text())
    assert coco["annotations"]
    manifest = json.loads((tmp_path / "dataset.json").read_text())
    assert manifest["clutter"] is True and manifest["close"] == 1.0 and manifest["styles"] == ["pepper"]
    assert manifest["picked"] == 1.0


@pytest.mark.parametrize("change, words", [
    ({"styles": ("fern",)}, "dataset: styles.0: Input should be 'simple', 'pepper' or 'highwire'"),
    ({"environments": ()}, "dataset: environments: "), ({"styles": ("pepper", "pepper")}, "styles: pepper, pepper: choose each once"),
    ({"close": 1.5}, "dataset: close: "), ({"sensor": -0.1}, "dataset: sensor: "), ({"picked": 2.0}, "dataset: picked: "),
    ({"distance": (0.8, 0.4)}, "dataset: distance: near 0.8 m is beyond far 0.4 m"),
])
def test_a_bad_dataset_choice_is_one_line_naming_its_field(change, words):
    with pytest.raises(UserError, match=re.escape(words)):
        DatasetSpec.of(**change)
