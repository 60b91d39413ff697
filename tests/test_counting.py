"""Yield counting and harvest plan on synthetic detections whose answer is known.

No rendering: a run directory is made of scene.json, config.yaml, a groundtruth.txt of
identity poses, empty frame images and a detections.json of noisy points around the
true fruit centres (1 cm sigma, 5-30 views per fruit).
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import cli

from renderloop.config import Config, CountingConfig, load_config
from renderloop.counting.assign import (
    NO_PLANT,
    lof_inliers,
    plants_by_volume,
    rows_by_table,
)
from renderloop.counting.cluster import (
    ClusterParams,
    cluster_row,
    count_rows,
    min_samples_for,
    resample,
    voted_labels,
)
from renderloop.counting.harvest import (
    nearest_neighbour,
    plan_harvest,
    tour_length,
    two_opt,
)
from renderloop.counting.stage import run_count
from renderloop.errors import UserError
from renderloop.io.atomic import dumps_json
from renderloop.io.tum import write_tum
from renderloop.rundir import files
from renderloop.rundir.stage import claim
from renderloop.rundir.files import read_counts, write_config
from renderloop.scene.model import Scene, read_scene

FRAMES = 40
PNG = b"\x89PNG\r\n\x1a\n"


def fruit_points(scene: Scene, rng: np.random.Generator, ripe: bool, skip_plants: tuple[int, ...] = ()) -> np.ndarray:
    """5-30 noisy views of every fruit of one class about its centre: 6.5 mm sigma a
    coordinate, a median error of 1 cm, as the shipped detector's points on paper seed 7."""
    clouds = [np.array(p.center) + rng.normal(0.0, 0.0065, size=(int(rng.integers(5, 31)), 3))
              for p in scene.peppers if p.ripe == ripe and p.plant not in skip_plants]
    return np.vstack(clouds)


def truth_per_plant(scene: Scene, ripe: bool) -> dict[int, int]:
    return {plant.id: sum(1 for p in scene.peppers_of(plant.id) if p.ripe == ripe) for plant in scene.plants}


def false_positives(scene: Scene, rng: np.random.Generator) -> np.ndarray:
    """Dense blobs (each seen 15 times) outside every plant volume: the table's side, the floor, above the canopy."""
    row = scene.rows[0]
    cx, cy, _ = row.table.center
    top = max(scene.plant(i).bounds.max[2] for i in row.plants)
    places = [(cx + 0.3, cy, 0.3), (cx - 0.6, cy + 0.4, 0.05), (cx, cy - 0.2, top + 0.15)]
    return np.vstack([np.array(place) + rng.normal(0.0, 0.01, size=(15, 3)) for place in places])


def detections_document(points: dict[str, np.ndarray], frames: int = FRAMES) -> dict:
    """Spread the points round-robin over the frames, as a detector would have reported them."""
    per_frame: list[list[dict]] = [[] for _ in range(frames)]
    k = 0
    for label, cloud in points.items():
        for point in cloud:
            per_frame[k % frames].append({"bbox": [10.0, 12.0, 40.0, 50.0], "score": 0.9, "label": label,
                                          "position": [float(v) for v in point]})
            k += 1
    per_frame[0].append({"bbox": [0.0, 0.0, 5.0, 5.0], "score": 0.6, "label": "ripe", "position": None})
    return {"model": "synthetic", "score_threshold": 0.5, "depth": "depth_sensor",
            "frames": [{"index": i, "timestamp": i * 0.5, "image": f"rgb/{i:06d}.png", "detections": d}
                       for i, d in enumerate(per_frame)]}


def make_run(run_dir: Path, config: Config, scene: Scene, points: dict[str, np.ndarray] | None) -> Path:
    claim(run_dir)  # marked ours, as `renderloop scene` marks a run directory
    write_config(run_dir, config)
    (run_dir / "scene.json").write_text(dumps_json(scene.model_dump(mode="json")), encoding="utf-8")
    write_tum(run_dir / "groundtruth.txt", np.arange(FRAMES) * 0.5, np.zeros((FRAMES, 3)),
              np.repeat(np.eye(3)[None], FRAMES, axis=0), "synthetic poses")
    (run_dir / "rgb").mkdir()
    for i in range(FRAMES):
        (run_dir / "rgb" / f"{i:06d}.png").write_bytes(PNG)
    if points is not None:
        (run_dir / "detections.json").write_text(json.dumps(detections_document(points)), encoding="utf-8")
    return run_dir


def synthetic_points(scene: Scene, seed: int = 1, skip_plants: tuple[int, ...] = ()) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {"ripe": fruit_points(scene, rng, True, skip_plants), "unripe": fruit_points(scene, rng, False)}




# --- the paper's rule and the fixed-size set ------------------------------------------------------


def test_min_samples_is_two_views_scaled_by_the_augmentation():
    assert min_samples_for(100, 500, 2) == 10  # every detection has 5 places in the set
    assert min_samples_for(120, 500, 2) == 10  # ceil(4.17) = 5
    assert min_samples_for(800, 500, 2) == 2  # subsampled: one place per kept detection
    assert min_samples_for(3, 500, 2) == 334
    assert min_samples_for(1, 500, 2) == 500  # capped at the set size


def test_resample_gives_every_detection_an_equal_share_or_subsamples():
    rng = np.random.default_rng(0)
    detections = rng.normal(size=(120, 3))
    points, original = resample(detections, 500, 0.0, rng)
    assert points.shape == (600, 3) and original.sum() == 120  # ceil(500 / 120) = 5 places each
    np.testing.assert_array_equal(points[:120], detections)
    _, copies = np.unique(points, axis=0, return_counts=True)
    assert set(copies) == {5}

    many = rng.normal(size=(900, 3))
    points, original = resample(many, 500, 0.01, rng)
    assert points.shape == (500, 3) and original.all()
    assert len(np.unique(points, axis=0)) == 500
    assert np.isin(points.view([("", float)] * 3), many.view([("", float)] * 3)).all()


def test_a_fruit_seen_once_is_not_counted_and_two_views_are():
    rng = np.random.default_rng(3)
    params = ClusterParams(points=500, eps=0.04, noise_std=0.01, min_views=2, method="dbscan")
    single = cluster_row(np.array([[0.0, 0.0, 1.0]]), params, rng)
    assert len(single.centers) == 0 and single.min_samples == 0
    far_apart = np.array([[0.0, 0.0, 1.0], [0.0, 0.5, 1.0], [0.0, 1.0, 1.0], [0.0, 1.0, 1.005]])
    found = cluster_row(far_apart, params, rng)
    assert found.min_samples == 250 and len(found.points) == 500
    np.testing.assert_allclose(found.centers, [[0.0, 1.0, 1.0025]], atol=1e-9)  # the only fruit seen twice


def test_a_detection_takes_the_class_most_detections_around_its_point_hold():
    rng = np.random.default_rng(4)
    green = np.array([0.0, 0.0, 1.0]) + rng.normal(0.0, 0.0065, (20, 3))  # one green fruit, called ripe in 3 of 20 views
    red = np.array([0.0, 0.08, 1.0]) + rng.normal(0.0, 0.0065, (12, 3))  # a ripe fruit touching it, a fruit's width away
    points, labels = np.vstack([green, red]), np.array([0] * 3 + [1] * 17 + [0] * 12)  # CLASSES: ripe 0, unripe 1
    assert voted_labels(points, labels, 0.04).tolist() == [1] * 20 + [0] * 12
    tie = np.array([[0.0, 0.0, 1.0], [0.0, 0.01, 1.0]])
    assert voted_labels(tie, np.array([0, 1]), 0.04).tolist() == [0, 1]  # a tie keeps each its own
    assert voted_labels(np.zeros((0, 3)), np.zeros(0, dtype=int), 0.04).tolist() == []


def test_a_green_fruit_called_ripe_in_a_few_views_is_counted_once_as_green(demo, tmp_path: Path):
    config, scene = demo
    points = synthetic_points(scene)
    green = next(p for p in scene.peppers if not p.ripe)
    mislabelled = np.array(green.center) + np.random.default_rng(2).normal(0.0, 0.0065, (3, 3))
    run = make_run(tmp_path / "run", config, scene, {"ripe": np.vstack([points["ripe"], mislabelled]),
                                                     "unripe": points["unripe"]})
    assert run_count(run, config)
    counts = read_counts(run)
    assert counts.total.estimate == counts.total.truth and counts.total.unripe_estimate == counts.total.unripe_truth


def test_a_fruit_seen_twice_is_counted_whatever_the_row_size():
    """500 / 120 is not whole: with exactly 500 points some detections would get 4 places,
    and two of them (8 points) would fall short of MinPts = 2 * 5."""
    params = ClusterParams(points=500, eps=0.04, noise_std=0.01, min_views=2, method="dbscan")
    grid = np.stack(np.meshgrid(np.arange(12), np.arange(10), indexing="ij"), axis=-1).reshape(-1, 2) * 0.3
    singles = np.column_stack([grid[:118], np.ones(118)])  # 118 fruit seen once, 30 cm apart
    twice = np.array([[5.0, 5.0, 1.0], [5.0, 5.02, 1.0]])
    for draw in range(5):
        found = cluster_row(np.vstack([singles, twice]), params, np.random.default_rng([5, draw]))
        assert found.min_samples == 10
        np.testing.assert_allclose(found.centers, [[5.0, 5.01, 1.0]], atol=1e-9)


@pytest.mark.parametrize("method", ["dbscan", "xi"])
def test_the_compiled_optics_graph_and_labels_are_scikit_learns_to_the_bit(method):
    """Rows like the counter's (fruit clouds, gaussian copies, points rounded to the cm so distances tie), and rows
    where no point is a core point: ordering, core distances, reachability, predecessors and labels all equal."""
    from scipy.spatial.distance import cdist
    from sklearn.cluster import OPTICS

    from renderloop.counting.optics import optics_graph, optics_labels

    rng = np.random.default_rng(11)
    for trial in range(6):
        n = int(rng.integers(2, 300))
        centres = rng.uniform(0.0, 0.6, size=(int(rng.integers(1, 15)), 3))
        detections = centres[rng.integers(0, len(centres), n)] + rng.normal(0.0, [0.004, 0.01, 0.05][trial % 3], (n, 3))
        points = resample(np.round(detections, 2) if trial % 2 else detections, 200, 0.005, rng)[0]
        distances, min_samples = cdist(points, points), min_samples_for(n, 200, 2)
        expected = OPTICS(min_samples=min_samples, max_eps=0.04, cluster_method=method, metric="precomputed",
                          xi=0.05).fit(distances)
        graph = optics_graph(distances, min_samples, 0.04)
        for ours, theirs in zip(graph, ("ordering_", "core_distances_", "reachability_", "predecessor_")):
            np.testing.assert_array_equal(ours, getattr(expected, theirs))
        np.testing.assert_array_equal(optics_labels(distances, min_samples, 0.04, method, 0.05), expected.labels_)


# --- layout ---------------------------------------------------------------------------------------


def test_points_go_to_the_plant_volume_that_holds_them(demo):
    _, scene = demo
    plant = scene.plant(1)
    low, high = np.array(plant.bounds.min), np.array(plant.bounds.max)
    inside = (low + high) / 2
    just_out = np.array([high[0] + 0.015, inside[1], inside[2]])  # within the 2 cm margin
    far_out = np.array([high[0] + 0.05, inside[1], inside[2]])
    np.testing.assert_array_equal(plants_by_volume(scene, np.array([inside, just_out, far_out]), 0.02),
                                  [1, 1, NO_PLANT])
    np.testing.assert_array_equal(plants_by_volume(scene, np.array([just_out]), 0.0), [NO_PLANT])


def test_rows_by_table_tells_the_two_blocks_apart(paper):
    _, scene = paper
    centers = np.array([row.table.center for row in scene.rows])
    points = centers + np.array([0.2, 0.9, 0.5])  # near each table, inside its length
    np.testing.assert_array_equal(rows_by_table(scene, points), [row.id for row in scene.rows])


def test_lof_drops_isolated_points_and_keeps_small_clusters():
    rng = np.random.default_rng(0)
    clusters = [np.array(c) + rng.normal(0, 0.01, size=(5, 3)) for c in ((0, 0, 1), (0, 0.15, 1), (0, 0.3, 1))]
    isolated = np.array([[0.3, 0.6, 1.2], [-0.4, -0.3, 0.7]])
    keep = lof_inliers(np.vstack([*clusters, isolated]), 4)
    assert keep[:15].all() and not keep[15:].any()


# --- counting -------------------------------------------------------------------------------------


def test_every_plant_is_counted_exactly_and_an_undetected_plant_gets_zero(demo, tmp_path: Path):
    config, scene = demo
    ripe_truth = truth_per_plant(scene, True)
    blind = max(ripe_truth, key=ripe_truth.get)  # the plant with most ripe fruit is never detected
    run = make_run(tmp_path / "run", config, scene, synthetic_points(scene, skip_plants=(blind,)))
    assert run_count(run, config)
    counts = read_counts(run).model_dump()
    unripe_truth = truth_per_plant(scene, False)
    for plant in counts["plants"]:
        assert plant["truth"] == ripe_truth[plant["id"]]
        assert plant["estimate"] == (0 if plant["id"] == blind else plant["truth"]), plant
        assert plant["unripe_estimate"] == plant["unripe_truth"] == unripe_truth[plant["id"]]
        assert len(plant["clusters"]) == plant["estimate"]
        for center in plant["clusters"]:  # every counted fruit sits on a true fruit of its plant
            gaps = [math.dist(center, p.center) for p in scene.peppers_of(plant["id"]) if p.ripe]
            assert min(gaps) < 0.015
    truth = sum(ripe_truth.values())
    total = counts["total"]
    assert total["truth"] == truth and total["estimate"] == truth - ripe_truth[blind] > 0
    assert total["error_pct"] == pytest.approx(-100 * ripe_truth[blind] / truth, abs=1e-4)
    assert total["exact_plants"] == pytest.approx(1 - 1 / len(scene.plants))
    row = counts["rows"][0]
    assert row["detections"] == sum(1 for _ in synthetic_points(scene, skip_plants=(blind,))["ripe"])
    assert counts["detections"]["no_position"] == 1
    assert (run / "counts" / "row_0.png").read_bytes()[:8] == PNG


def test_false_positives_outside_the_volumes_are_removed(demo):
    config, scene = demo
    clean = synthetic_points(scene)["ripe"]
    fakes = false_positives(scene, np.random.default_rng(5))
    counting = config.counting
    [with_fakes] = count_rows(scene, np.vstack([clean, fakes]), "ripe", counting, config.seed)
    [without] = count_rows(scene, clean, "ripe", counting, config.seed)
    assert len(with_fakes.removed) == len(fakes)
    assert with_fakes.clusters.n_init == len(clean)
    np.testing.assert_allclose(with_fakes.clusters.centers, without.clusters.centers)
    assert len(without.clusters.centers) == sum(truth_per_plant(scene, True).values())


def test_without_the_layout_lof_and_the_nearest_table_count_the_same_fruit(demo):
    config, scene = demo
    rng = np.random.default_rng(9)
    clean = fruit_points(scene, rng, True)
    scattered = np.array(scene.rows[0].table.center) + rng.uniform(-1, 1, size=(12, 3)) * [0.4, 1.0, 0.3] + [0, 0, 0.6]
    counting = CountingConfig(use_layout=False)
    [row] = count_rows(scene, np.vstack([clean, scattered]), "ripe", counting, config.seed)
    for point in scattered:  # every isolated point is dropped, with a few tail points of the real fruit
        assert np.any(np.all(row.removed == point, axis=1))
    assert len(clean) > row.clusters.n_init > 0.9 * len(clean)
    counted = np.bincount(row.plants, minlength=len(scene.plants))
    expected = truth_per_plant(scene, True)
    assert [int(c) for c in counted] == [expected[plant.id] for plant in scene.plants]


def test_same_seed_gives_the_same_bytes(demo, tmp_path: Path):
    config, scene = demo
    points = synthetic_points(scene)
    points["ripe"] = np.vstack([points["ripe"]] * 3)  # over 500 points: the subsample is random
    outputs = []
    for name in ("a", "b"):
        run = make_run(tmp_path / name, config, scene, points)
        run_count(run, config)
        outputs.append(((run / "counts.json").read_bytes(), (run / "harvest.json").read_bytes()))
    assert outputs[0] == outputs[1]
    assert json.loads(outputs[0][0])["rows"][0]["detections"] > 500


@pytest.mark.parametrize(
    ("change", "problem"),
    [
        (lambda d: d["frames"][1]["detections"][0].update(label="overripe"), "label"),
        (lambda d: d["frames"][1]["detections"][0].update(position=[1.0, float("nan"), 1.0]), "position"),
        (lambda d: d["frames"][1]["detections"][0].update(bbox=[1.0, 2.0, 3.0]), "bbox"),
        (lambda d: d["frames"][1]["detections"][0].update(bbox=[30.0, 2.0, 3.0, 9.0]), "x0 <= x1"),
        (lambda d: d["frames"][1]["detections"][0].update(score="0.9"), "score"),
        (lambda d: d["frames"][1]["detections"][0].pop("position"), "position"),
        (lambda d: d["frames"][1]["detections"][0].update(colour="red"), "unknown field"),
        (lambda d: d.pop("frames"), "frames"),
        (lambda d: d.update(depth=5), "depth"),
        (lambda d: d["frames"][2].update(index=FRAMES), "groundtruth.txt has 40 frames"),
        (lambda d: d["frames"][2].update(index=1), "appears twice"),
        (lambda d: d["frames"][3].update(image="rgb/missing.png"), "not a file"),
        (lambda d: d["frames"][3].update(image="../rgb/000003.png"), "not a file"),
    ],
)
def test_malformed_detections_are_one_line_errors(demo, tmp_path: Path, change, problem):
    config, scene = demo
    run = make_run(tmp_path / "run", config, scene, synthetic_points(scene))
    document = json.loads((run / "detections.json").read_text())
    change(document)
    (run / "detections.json").write_text(json.dumps(document))
    with pytest.raises(UserError) as error:
        run_count(run, config)
    message = str(error.value)
    assert "detections.json" in message and problem in message and "\n" not in message
    assert not (run / "counts.json").exists()


def test_detections_that_are_not_json_are_an_error(demo, tmp_path: Path):
    config, scene = demo
    run = make_run(tmp_path / "run", config, scene, None)
    (run / "detections.json").write_text('{"model": "x", "frames": [')
    with pytest.raises(UserError, match="detections.json: Invalid JSON"):
        run_count(run, config)


# --- harvest --------------------------------------------------------------------------------------


def test_two_opt_untangles_a_crossed_tour():
    start = np.array([0.0, 0.0])
    square = np.array([[0.0, 1.0], [1.0, 0.0], [1.0, 1.0]])  # visiting in this order crosses itself
    assert tour_length(start, square, [0, 1, 2]) == pytest.approx(2 + 2 * math.sqrt(2))
    order = two_opt(start, square, [0, 1, 2])
    assert tour_length(start, square, order) == pytest.approx(4.0)
    assert nearest_neighbour(start, np.array([[3.0, 0.0], [1.0, 0.0], [2.0, 0.0]])) == [1, 2, 0]


def test_harvest_visits_each_bearing_plant_once_and_adds_up(paper):
    _, scene = paper
    estimates = {plant.id: len([p for p in scene.peppers_of(plant.id) if p.ripe]) for plant in scene.plants}
    plan = plan_harvest(scene, estimates, 3)
    chosen = sorted(plant_id for plant_id, n in estimates.items() if n >= 3)
    visited = [stop["id"] for stop in plan["stops"]]
    assert sorted(visited) == chosen and len(set(visited)) == len(visited) > 5
    legs = [stop["leg_distance"] for stop in plan["stops"]]
    assert plan["total_distance"] == pytest.approx(sum(legs) + plan["return_distance"], abs=1e-5)
    assert plan["total_expected_ripe"] == sum(estimates[i] for i in chosen)
    here = np.array(scene.workstation.center[:2])
    for stop in plan["stops"]:
        assert stop["row"] == scene.plant(stop["id"]).row and stop["expected_ripe"] == estimates[stop["id"]]
        assert stop["leg_distance"] == pytest.approx(np.linalg.norm(np.array(stop["position"][:2]) - here), abs=1e-6)
        here = np.array(stop["position"][:2])
    greedy = nearest_neighbour(np.array(scene.workstation.center[:2]),
                               np.array([scene.plant(i).position[:2] for i in chosen]))
    greedy_length = tour_length(np.array(scene.workstation.center[:2]),
                                np.array([scene.plant(i).position[:2] for i in chosen]), greedy)
    assert plan["total_distance"] <= greedy_length + 1e-6


# --- the stage and the CLI ------------------------------------------------------------------------


def test_count_has_help():
    result = subprocess.run([sys.executable, "-m", "renderloop", "count", "--help"], check=False, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "--no-layout" in result.stdout and "--force" in result.stdout


def test_cli_counts_a_run_directory_then_skips_and_redoes(monkeypatch, capsys, tmp_path: Path):
    out = tmp_path / "run"
    code, _, _ = cli(monkeypatch, capsys, "scene", "--preset", "demo", "--out", str(out))
    assert code == 0
    config = load_config("demo")
    scene = Scene.model_validate_json((out / "scene.json").read_text())
    code, _, stderr = cli(monkeypatch, capsys, "count", str(out))
    assert code == 2 and stderr.count("\n") == 1 and "groundtruth.txt" in stderr and "renderloop fly" in stderr

    write_tum(out / "groundtruth.txt", np.arange(FRAMES) * 0.5, np.zeros((FRAMES, 3)),
              np.repeat(np.eye(3)[None], FRAMES, axis=0), "synthetic poses")
    code, _, stderr = cli(monkeypatch, capsys, "count", str(out))
    assert code == 2 and stderr.count("\n") == 1
    assert "missing detections.json" in stderr and "renderloop detect" in stderr

    (out / "rgb").mkdir()
    for i in range(FRAMES):
        (out / "rgb" / f"{i:06d}.png").write_bytes(PNG)
    (out / "detections.json").write_text(json.dumps(detections_document(synthetic_points(scene))))
    code, stdout, _ = cli(monkeypatch, capsys, "count", str(out))
    truth = sum(truth_per_plant(scene, True).values())
    assert code == 0 and "wrote" in stdout and f"ripe: {truth} counted, {truth} true" in stdout
    counts, harvest = read_counts(out).model_dump(), json.loads((out / "harvest.json").read_text())
    assert counts["settings"]["use_layout"] is True and counts["settings"]["seed"] == config.seed
    assert counts["total"]["exact_plants"] == 1.0
    assert harvest["total_expected_ripe"] == truth
    assert (out / "counts" / "row_0.png").read_bytes()[:8] == PNG

    stamp = (out / "counts.json").stat().st_mtime_ns
    code, stdout, _ = cli(monkeypatch, capsys, "count", str(out))
    assert code == 0 and "already complete" in stdout and (out / "counts.json").stat().st_mtime_ns == stamp

    code, stdout, _ = cli(monkeypatch, capsys, "count", str(out), "--no-layout")  # other settings: redone
    assert code == 0 and "wrote" in stdout and read_counts(out).settings["use_layout"] is False

    (out / "detections.json").write_text('{"model": 1}')  # newer input: redone, and refused
    code, _, stderr = cli(monkeypatch, capsys, "count", str(out))
    assert code == 2 and stderr.count("\n") == 1 and "detections.json" in stderr


def test_counts_tell_fruit_the_scan_never_showed_from_the_detectors_misses(complete_run: Path, tmp_path: Path):
    from PIL import Image

    from renderloop.render.frames import read_png

    run = tmp_path / "run"
    shutil.copytree(complete_run, run)
    before = read_counts(run)
    assert before.total.unseen is not None and before.total.seen_error_pct is not None
    assert before.total.unseen == sum(p.unseen for p in before.plants)
    masks = sorted((run / "masks").iterdir())
    shown = {int(i) for path in masks for i in np.unique(read_png(path, np.uint16)) if i}
    scene = read_scene(run)
    hidden = next(p for p in scene.peppers if p.ripe and p.id in shown)
    for path in masks:  # as if every view had the fruit behind a leaf
        mask = read_png(path, np.uint16)
        Image.fromarray(np.where(mask == hidden.id, 0, mask).astype(np.uint16)).save(path)
    run_count(run, files.read_config(run), force=True)
    after = read_counts(run)
    plant = {p.id: p for p in after.plants}[hidden.plant]
    assert plant.unseen == {p.id: p for p in before.plants}[hidden.plant].unseen + 1
    assert after.total.unseen == before.total.unseen + 1
