"""The training set: random scenes and views, boxes from masks with the ignore rules, resumable COCO build."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from renderloop.dataset.build import build_dataset
from renderloop.dataset.labels import MIN_SIDE, MIN_VISIBLE, ignore_reason, pepper_boxes, pepper_vertices
from renderloop.config.dataset import DatasetSpec
from renderloop.dataset.scenes import FORMAT_VERSION, dataset_scene
from renderloop.dataset.views import random_view
from renderloop.errors import UserError
from renderloop.render.camera import Intrinsics
from renderloop.render.raster import RasterRenderer
from renderloop.io.ownership import LEDGER, read_ledger
from renderloop.perception.scoring import MIN_SIDE as FINDABLE

TINY = DatasetSpec(seed=3, width=64, height=48, views_per_scene=2, samples=(1,), val_every=2)


def test_dataset_scenes_are_reproducible_varied_and_all_bearing():
    spec = DatasetSpec(seed=5)
    (config_a, scene_a), (config_b, scene_b) = dataset_scene(spec, 0), dataset_scene(spec, 1)
    assert dataset_scene(spec, 0)[1] == scene_a
    assert all(plant.bearing for plant in scene_a.plants) and scene_a.peppers
    assert config_a.seed != config_b.seed and scene_a.peppers != scene_b.peppers
    assert (config_a.camera.width, config_a.camera.height) == (320, 240)
    assert config_a.renderer.samples in spec.samples


def _ray_hits_box(origin: np.ndarray, direction: np.ndarray, low: np.ndarray, high: np.ndarray) -> bool:
    with np.errstate(divide="ignore"):
        t1, t2 = (low - origin) / direction, (high - origin) / direction
    near, far = np.minimum(t1, t2).max(), np.maximum(t1, t2).min()
    return far >= max(near, 0.0)


def test_views_keep_clear_of_plants_and_tables_and_aim_at_a_plant():
    _, scene = dataset_scene(DatasetSpec(seed=9), 2)
    rng = np.random.default_rng(0)
    for _ in range(200):
        pose = random_view(scene, rng)
        position, axis = pose[:3, 3], pose[:3, 2]
        assert not any(plant.bounds.contains(tuple(position), 0.04) for plant in scene.plants)
        assert np.allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-9)
        assert axis[2] < np.sin(np.radians(21))  # never looks up more than 20 degrees (plus roll)
        assert any(_ray_hits_box(position, axis, np.asarray(p.bounds.min) - 0.02, np.asarray(p.bounds.max) + 0.02)
                   for p in scene.plants)


@pytest.mark.parametrize("distance_range", [(0.3, 1.2), (0.3, 0.65)])
def test_views_keep_to_their_distance_from_the_plant_axis(distance_range):
    _, scene = dataset_scene(DatasetSpec(seed=9), 2)
    rng = np.random.default_rng(3)
    axes = np.array([plant.position[:2] for plant in scene.plants])
    near, far = distance_range[0] - 1e-9, distance_range[1] + 1e-9
    seen = []  # the viewed plant is one whose axis is within the range (a neighbour may be nearer)
    for _ in range(200):
        distances = np.linalg.norm(axes - random_view(scene, rng, distance_range)[:2, 3], axis=1)
        in_range = distances[(distances >= near) & (distances <= far)]
        assert in_range.size
        seen.append(in_range.min())
    assert np.median(seen) < np.mean(distance_range)  # drawn nearer more often, as scans are


def test_boxes_cover_the_mask_and_unhidden_fruit_are_fully_visible():
    spec = DatasetSpec(seed=4)
    config, scene = dataset_scene(spec, 0)
    intrinsics = Intrinsics.from_config(config.camera)
    peppers = {p.id: p for p in scene.peppers}
    meshes = pepper_vertices(scene)
    rng = np.random.default_rng(1)
    fractions, records_seen = [], 0
    with RasterRenderer(scene, config, intrinsics) as renderer:
        for _ in range(12):
            pose = random_view(scene, rng)
            mask = renderer.render(pose).mask
            for record in pepper_boxes(mask, peppers, meshes, pose, intrinsics, config.camera.clip[0]):
                records_seen += 1
                x0, y0, x1, y1 = record["bbox"]
                pixels = mask == record["pepper_id"]
                assert pixels[y0:y1, x0:x1].sum() == pixels.sum() == record["pixels"]
                assert pixels[y0, x0:x1].any() and pixels[y1 - 1, x0:x1].any() and pixels[y0:y1, x0].any() and pixels[y0:y1, x1 - 1].any()
                assert 0 < record["visible_fraction"] <= 1
                assert record["label"] == ("ripe" if peppers[record["pepper_id"]].ripe else "unripe")
                if min(x1 - x0, y1 - y0) < MIN_SIDE:
                    assert record["ignore"] == "tiny"
                fractions.append(record["visible_fraction"])
    assert records_seen > 20
    # the convex hull of the projected fruit bounds its silhouette: fruit in plain view reach nearly 1
    assert np.percentile(fractions, 90) > 0.85


def test_the_neighbouring_rows_fruit_are_labelled_one_by_one_from_their_shared_mask_id():
    """Their masks share one id: every such pixel goes to one fruit whose projected mesh holds it at its depth, the
    nearer of two that overlap, and each fruit's box is the extent of its pixels, with the scene's fruit rules."""
    from matplotlib.path import Path as PolygonPath
    from scipy.spatial import ConvexHull

    from renderloop.dataset.labels import neighbour_fruit_boxes
    from renderloop.scene.model import NEIGHBOUR_FRUIT_ID
    from renderloop.scene.objects import neighbour_fruit

    config, scene = dataset_scene(DatasetSpec(seed=21, styles=("highwire",), environments=("film",)), 0)
    fruit = neighbour_fruit(scene.environment)
    assert len(fruit) > 100 and all(len(vertices) > 20 for _, vertices in fruit)
    intrinsics, near = Intrinsics.from_config(config.camera), config.camera.clip[0]
    rng = np.random.default_rng(3)
    marked_total, records = 0, []
    with RasterRenderer(scene, config, intrinsics) as renderer:
        for _ in range(5):
            pose = random_view(scene, rng)
            frame = renderer.render(pose)
            marked = frame.mask == NEIGHBOUR_FRUIT_ID
            found = neighbour_fruit_boxes(frame.mask, frame.depth, fruit, pose, intrinsics, near)
            assert sum(record["pixels"] for record in found) >= 0.99 * marked.sum()  # nearly every pixel is a fruit's
            for record in found:
                x0, y0, x1, y1 = record["bbox"]
                assert record["pepper_id"] is None and record["label"] in ("ripe", "unripe")
                assert marked[y0:y1, x0:x1].sum() >= record["pixels"] and 0 < record["visible_fraction"] <= 1
                assert (record["ignore"] == "tiny") == (min(x1 - x0, y1 - y0) < MIN_SIDE) or record["ignore"] == "occluded"
            marked_total, records = marked_total + marked.sum(), records + found
    assert marked_total > 200 and any(record["ignore"] is None for record in records)
    # two fruit where one hides the other: each marked pixel is the nearer one's
    front, back = fruit[0], fruit[1]
    centre = front[1].mean(axis=0)
    pose = np.eye(4)
    pose[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]  # optical axes x, y, z: world +x, -z (down), +y (ahead)
    pose[:3, 3] = centre - [0.0, 0.6, 0.0]
    behind = (back[0], back[1] - back[1].mean(axis=0) + centre + [0.02, 0.1, 0.0])  # 10 cm further, 2 cm aside
    mask, depth = np.zeros((intrinsics.height, intrinsics.width), np.uint16), np.zeros((intrinsics.height, intrinsics.width), np.float32)
    for _, vertices in (behind, front):  # the nearer drawn last, as a renderer's depth test leaves it
        local = (vertices - pose[:3, 3]) @ pose[:3, :3]
        uv = intrinsics.project(local)
        cols, rows = np.meshgrid(np.arange(intrinsics.width), np.arange(intrinsics.height))
        hull = PolygonPath(uv[ConvexHull(uv).vertices])
        inside = hull.contains_points(np.column_stack([cols.ravel(), rows.ravel()])).reshape(cols.shape)
        mask[inside], depth[inside] = NEIGHBOUR_FRUIT_ID, local[:, 2].mean()
    both = neighbour_fruit_boxes(mask, depth, [behind, front], pose, intrinsics, near)
    assert len(both) == 2 and sum(r["pixels"] for r in both) == (mask > 0).sum()
    far, close = sorted(both, key=lambda r: r["visible_fraction"])
    assert close["visible_fraction"] > 0.95 and far["visible_fraction"] < 0.9


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_build_resumes_grows_and_is_reproducible(tmp_path: Path):
    grown, whole = tmp_path / "grown", tmp_path / "whole"
    assert build_dataset(grown, 3, TINY) == 3
    first = _files(grown / "images")
    (grown / "labels" / "000002.json").unlink()  # as if killed before its label landed
    assert build_dataset(grown, 4, TINY) == 2
    assert build_dataset(whole, 4, TINY) == 4
    assert {k: v for k, v in _files(grown / "images").items() if k in first} == first
    assert _files(grown) == _files(whole) | {LEDGER: _files(grown)[LEDGER]}  # the same files, listed in another order
    assert sorted(read_ledger(grown)) == sorted(read_ledger(whole))
    train = json.loads((whole / "annotations" / "instances_train.json").read_text())
    val = json.loads((whole / "annotations" / "instances_val.json").read_text())
    assert [i["file_name"] for i in train["images"]] == ["images/000000.jpg", "images/000001.jpg"]
    assert [i["file_name"] for i in val["images"]] == ["images/000002.jpg", "images/000003.jpg"]
    assert {c["name"] for c in train["categories"]} == {"ripe", "unripe"}
    for ann in train["annotations"] + val["annotations"]:
        x, y, w, h = ann["bbox"]
        assert w > 0 and h > 0 and x + w <= 64 and y + h <= 48 and ann["category_id"] in (1, 2)
    assert (whole / "preview.png").is_file()
    assert not list(whole.rglob(".*.partial"))


def test_a_hidden_fruit_is_a_target_once_the_scoring_would_ask_for_it_and_a_set_of_the_old_rule_is_relabelled(tmp_path: Path):
    hidden = MIN_VISIBLE / 2
    assert ignore_reason((0, 0, MIN_SIDE - 1, 40), 1.0, MIN_SIDE) == "tiny"
    assert ignore_reason((0, 0, FINDABLE - 1, 40), hidden, MIN_SIDE) == "occluded"  # a few pixels of a fruit: no target
    assert ignore_reason((0, 0, FINDABLE, 40), hidden, MIN_SIDE) is None  # findable in a scored frame, so a target
    assert ignore_reason((0, 0, FINDABLE - 1, 40), MIN_VISIBLE, MIN_SIDE) is None
    # a set labelled by the earlier rule (every fruit under MIN_VISIBLE ignored) follows this one when built again
    build_dataset(tmp_path, 2, TINY)
    images = _files(tmp_path / "images")
    label = tmp_path / "labels" / "000000.json"
    record = json.loads(label.read_text())
    old = {"pepper_id": 10**6, "bbox": [1, 2, 1 + FINDABLE, 3 + FINDABLE], "label": "ripe", "pixels": 90, "visible_fraction": hidden,
           "ignore": "occluded"}
    label.write_text(json.dumps({**record, "peppers": record["peppers"] + [old]}))
    assert build_dataset(tmp_path, 2, TINY) == 0  # nothing rendered again
    assert json.loads(label.read_text())["peppers"][-1] == {**old, "ignore": None}
    coco = json.loads((tmp_path / "annotations" / "instances_train.json").read_text())
    assert [a["iscrowd"] for a in coco["annotations"] if a["pepper_id"] == 10**6] == [0]
    assert _files(tmp_path / "images") == images


def test_a_dataset_of_other_settings_is_not_mixed(tmp_path: Path):
    build_dataset(tmp_path, 1, TINY)
    other = DatasetSpec(seed=4, width=64, height=48, views_per_scene=2, samples=(1,), val_every=2)
    with pytest.raises(UserError, match="other settings"):
        build_dataset(tmp_path, 1, other)
    with pytest.raises(UserError, match="other settings"):
        build_dataset(tmp_path, 1, TINY.model_copy(update={"distance": (0.3, 0.65)}))
    manifest = tmp_path / "dataset.json"
    recorded = json.loads(manifest.read_text())
    manifest.write_text(json.dumps({**recorded, "format_version": 2}))  # images of another renderer: not mixed either
    with pytest.raises(UserError, match=rf"format 2, made by another renderloop \(this one renders format {FORMAT_VERSION}"):
        build_dataset(tmp_path, 1, TINY)
    with pytest.raises(UserError, match="--images 0"):
        build_dataset(tmp_path, 0, TINY)
