"""The interval of each plant's, row's and the total ripe count, on synthetic detections whose answer is known.

No rendering: cameras stand on a ring about each plant of the demo scene and every frame
sees every ripe fruit of its plant at its centre, 4 mm sigma. The counting set is shrunk
(`points` 100, 2 draws) so that a count takes a fraction of a second; the rules are the
same. The model's parameters are the config's where a test says what the shipped model
must do, and set explicitly where a test checks a mechanism.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from test_counting import make_run, synthetic_points

from renderloop.config import Config, CountingConfig, IntervalConfig
from renderloop.counting.cluster import class_points, count_rows, rng_for
from renderloop.counting.online import OnlineCounter
from renderloop.counting.stage import run_count
from renderloop.counting.summary import count_scan
from renderloop.counting.uncertainty import (
    PlantEvidence,
    central_interval,
    evidence,
    from_evidence,
    poisson_binomial_pmf,
    poisson_pmf,
    uncertainty,
    view_spread,
)
from renderloop.errors import UserError
from renderloop.rundir import files
from renderloop.rundir.models import Counts, Detection, DetectionFrame, Detections
from renderloop.scene.model import Plant, Scene

FAST = CountingConfig(points=100, interval=IntervalConfig(redraws=2))
NOISE = 0.004  # m, sigma of a detection about its fruit's centre


def middle(plant: Plant) -> np.ndarray:
    low, high = np.array(plant.bounds.min), np.array(plant.bounds.max)
    return (low + high) / 2


def ring(plant: Plant, azimuths: np.ndarray, radius: float = 0.5) -> np.ndarray:
    """Camera positions about the plant's middle, at its height."""
    return middle(plant) + radius * np.column_stack([np.cos(azimuths), np.sin(azimuths), np.zeros(len(azimuths))])


class Scan:
    """Frames and camera positions built up view by view: each view sees the given points, 4 mm noise."""

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)
        self.frames: list[DetectionFrame] = []
        self.cameras: dict[int, np.ndarray] = {}

    def view(self, camera: np.ndarray, points: list[np.ndarray], label: str = "ripe") -> None:
        index = len(self.frames)
        detections = [Detection(bbox=(10.0, 10.0, 30.0, 30.0), score=0.9, label=label,
                                position=tuple(float(v) for v in np.asarray(p) + self.rng.normal(0.0, NOISE, 3)))
                      for p in points]
        self.frames.append(DetectionFrame(index=index, timestamp=index * 0.5, image=f"rgb/{index:06d}.png",
                                          detections=detections))
        self.cameras[index] = np.asarray(camera, dtype=float)

    def all_sides(self, scene: Scene, views: int = 6) -> Scan:
        """Every plant from `views` cameras all round it, each seeing all its ripe fruit."""
        for plant in scene.plants:
            fruit = [np.array(p.center) for p in scene.peppers_of(plant.id) if p.ripe]
            for camera in ring(plant, np.linspace(0.0, 2 * math.pi, views, endpoint=False)):
                self.view(camera, fruit)
        return self


def ripe_truth(scene: Scene) -> dict[int, int]:
    return {plant.id: sum(p.ripe for p in scene.peppers_of(plant.id)) for plant in scene.plants}


def empty_spot(scene: Scene, plant: Plant) -> np.ndarray:
    """A point inside the plant's box at least 12 cm from every fruit: where a false cluster can stand alone."""
    low, high = np.array(plant.bounds.min), np.array(plant.bounds.max)
    centres = np.array([p.center for p in scene.peppers])
    grid = np.stack(np.meshgrid(*[np.linspace(lo + 0.03, hi - 0.03, 9) for lo, hi in zip(low, high)]), -1).reshape(-1, 3)
    gaps = np.linalg.norm(grid[:, None] - centres[None], axis=2).min(axis=1)
    assert gaps.max() > 0.12
    return grid[int(np.argmax(gaps))]


@pytest.fixture(scope="module")
def scene(demo) -> Scene:
    _, scene = demo
    assert max(ripe_truth(scene).values()) >= 2
    return scene


@pytest.fixture(scope="module")
def all_round(scene) -> dict[int, PlantEvidence]:
    """The evidence of a scan that saw every fruit from all round."""
    scan = Scan().all_sides(scene)
    return evidence(scene, scan.frames, scan.cameras, FAST, seed=0)


@pytest.fixture(scope="module")
def counted_run(demo, tmp_path_factory) -> tuple[Config, Path]:
    """A run directory of synthetic detections counted with the intervals."""
    config, scene = demo
    config = config.override({"counting": FAST})
    run = make_run(tmp_path_factory.mktemp("uncertainty") / "run", config, scene, synthetic_points(scene))
    assert run_count(run, config)
    return config, run


# --- the pieces -----------------------------------------------------------------------------------


def test_redraw_zero_is_the_counts_own_stream_and_every_redraw_another():
    def first(generator: np.random.Generator) -> float:
        return float(generator.random())

    assert first(rng_for(7, 2, "ripe")) == first(np.random.default_rng(np.random.SeedSequence([7, 2, 0])))
    assert first(rng_for(7, 2, "ripe", 0)) == first(rng_for(7, 2, "ripe"))
    draws = {first(rng_for(7, 2, "ripe", draw)) for draw in range(8)} | {first(rng_for(7, 2, "unripe"))}
    assert len(draws) == 9


def test_the_distributions_are_exact_and_the_interval_is_their_central_quantiles():
    np.testing.assert_allclose(poisson_binomial_pmf([0.5, 0.5]), [0.25, 0.5, 0.25])
    pmf = poisson_pmf(2.0)
    assert pmf.sum() == pytest.approx(1.0) and pmf[3] == pytest.approx(math.exp(-2) * 8 / 6)
    np.testing.assert_array_equal(poisson_pmf(0.0), [1.0])
    assert central_interval(np.array([0.0, 0.0, 1.0]), 0.9) == (2, 2)
    assert central_interval(np.array([0.05, 0.9, 0.05]), 0.9) == (1, 1)  # 5 % may be left out on each side
    assert central_interval(np.array([0.06, 0.88, 0.06]), 0.9) == (0, 2)
    assert central_interval(np.array([0.2, 0.8]), 0.9) == (0, 1)


def test_the_view_spread_is_the_widest_angle_between_two_views():
    centre = np.zeros(3)
    assert view_spread(centre, np.array([[1.0, 0, 0]])) == 0.0
    assert view_spread(centre, np.array([[1.0, 0, 0], [0, 2.0, 0], [0.5, 0.5, 0]])) == pytest.approx(math.pi / 2)
    assert view_spread(centre, np.array([[1.0, 0, 0], [-3.0, 0, 0]])) == pytest.approx(math.pi)


# --- plants ---------------------------------------------------------------------------------------


def test_a_plant_whose_fruit_are_seen_many_times_from_all_sides_gets_a_zero_width_interval_equal_to_the_truth(
        scene, all_round):
    found = from_evidence(scene, all_round, FAST.interval)  # the shipped model's parameters
    for plant_id, truth in ripe_truth(scene).items():
        plant = found.plants[plant_id]
        assert (plant.low, plant.estimate, plant.high) == (truth, truth, truth) and plant.settled
        assert len(plant.weak_centers) == 0 and list(plant.redraw_counts) == [truth] * 2
        assert all(cluster.spread > 2.0 for cluster in plant.clusters)  # seen from all round


def test_a_fruit_seen_only_twice_from_one_side_is_weak_and_widens_the_interval_downward(scene):
    plant = max(scene.plants, key=lambda p: ripe_truth(scene)[p.id])
    spot = empty_spot(scene, plant)
    scan = Scan().all_sides(scene)
    for camera in ring(plant, np.radians([0.0, 4.0])):  # two views 4° apart: a false detection, or a fruit barely seen
        scan.view(camera, [spot])
    counting = FAST.model_copy(update={"interval": IntervalConfig(redraws=3, weak_real=0.5, hidden=0.0, hidden_per_lone=0.0)})
    found = uncertainty(scene, scan.frames, scan.cameras, counting, seed=0).plants[plant.id]
    truth = ripe_truth(scene)[plant.id]
    assert found.estimate == truth + 1  # the count takes it for a fruit ...
    np.testing.assert_allclose(found.weak_centers, [spot], atol=0.01)  # ... the uncertainty for a weak one
    weak = next(c for c in found.clusters if np.linalg.norm(c.center - spot) < 0.01)
    assert weak.support == 2 and weak.margin < 2 and weak.spread < math.radians(10)
    assert (found.low, found.high) == (truth, truth + 1) and not found.settled
    assert found.pmf[truth] == pytest.approx(0.5) and found.pmf[truth + 1] == pytest.approx(0.5)


def test_a_fruit_seen_often_but_from_one_side_only_is_weak(scene):
    plant = scene.plants[0]
    spot = empty_spot(scene, plant)
    scan = Scan().all_sides(scene)
    for camera in ring(plant, np.radians(np.linspace(0.0, 10.0, 8))):
        scan.view(camera, [spot])
    found = uncertainty(scene, scan.frames, scan.cameras, FAST, seed=0).plants[plant.id]
    weak = next(c for c in found.clusters if np.linalg.norm(c.center - spot) < 0.01)
    assert weak.support == 8 and weak.margin >= FAST.interval.weak_margin and weak.spread < FAST.interval.min_spread
    assert len(found.weak_centers) == 1


def test_a_fruit_seen_once_is_a_lone_detection_where_to_look_again_and_widens_the_interval_upward_a_stray_view_does_not(scene):
    plant = scene.plants[0]
    spot = empty_spot(scene, plant)
    fruit = np.array(next(p.center for p in scene.peppers_of(plant.id) if p.ripe))
    scan = Scan().all_sides(scene)
    scan.view(ring(plant, np.zeros(1))[0], [spot, fruit + [0.0, 0.0, 0.03]])  # a fruit seen once; a stray 3 cm off
    counting = FAST.model_copy(update={"interval": IntervalConfig(redraws=2, hidden=0.0, hidden_per_lone=0.5)})
    gathered = evidence(scene, scan.frames, scan.cameras, counting, seed=0)
    assert gathered[plant.id].lone == (1, 1) and all(e.lone == (0, 0) for i, e in gathered.items() if i != plant.id)
    found = from_evidence(scene, gathered, counting.interval).plants[plant.id]
    truth = ripe_truth(scene)[plant.id]
    assert found.low == found.estimate == truth < found.high
    assert found.lone_points.shape == (1, 3) and np.linalg.norm(found.lone_points[0] - spot) < 4 * NOISE  # the point itself


def test_the_estimate_credits_each_fruit_seen_once_with_the_lone_credit_rounded_per_plant(scene):
    a, b = scene.plants[0], scene.plants[1]
    scan = Scan().all_sides(scene)
    for plant in (a, b):  # one fruit seen once in each of two plants
        scan.view(ring(plant, np.zeros(1))[0], [empty_spot(scene, plant)])
    gathered = evidence(scene, scan.frames, scan.cameras, FAST, seed=0)
    truth = ripe_truth(scene)
    for credit, added in ((0.0, 0), (0.4, 0), (0.5, 1), (1.0, 1)):
        found = from_evidence(scene, gathered, FAST.interval, credit)
        for plant in scene.plants:
            assert found.plants[plant.id].estimate == truth[plant.id] + (added if plant.id in (a.id, b.id) else 0)
            assert len(found.plants[plant.id].clusters) == truth[plant.id]  # the clusters stay what they are
        assert found.total.estimate == sum(truth.values()) + 2 * added  # 0.4: 0.8 of a fruit in all, none in a plant
    assert uncertainty(scene, scan.frames, scan.cameras, FAST.model_copy(update={"lone_credit": 1.0}),
                       seed=0).total.estimate == sum(truth.values()) + 2


def test_a_green_fruit_seen_once_adds_the_unripe_lone_credit_to_its_plants_green_estimate(scene):
    plant = next(plant for plant in scene.plants if any(not p.ripe for p in scene.peppers_of(plant.id)))
    once = next(np.array(p.center) for p in scene.peppers_of(plant.id) if not p.ripe)
    scan = Scan().all_sides(scene)
    for other in scene.plants:  # every green fruit seen from all round but one, seen once
        green = [np.array(p.center) for p in scene.peppers_of(other.id) if not p.ripe]
        green = [center for center in green if not np.array_equal(center, once)]
        for camera in ring(other, np.linspace(0.0, 2 * math.pi, 6, endpoint=False)):
            scan.view(camera, green, label="unripe")
    scan.view(ring(plant, np.zeros(1))[0], [once], label="unripe")
    poses = np.tile(np.eye(4), (len(scan.frames), 1, 1))
    poses[:, :3, 3] = [scan.cameras[index] for index in range(len(scan.frames))]
    detections = Detections(model="synthetic", score_threshold=0.5, frames=scan.frames)
    for credit, added in ((0.0, 0), (0.4, 0), (0.5, 1), (1.0, 1)):
        counting = FAST.model_copy(update={"unripe_lone_credit": credit})
        counts = count_scan(scene, detections, poses, counting, seed=0, seen=None).counts
        for found in counts.plants:
            missed = int(found.id == plant.id)  # the fruit seen once is no cluster
            assert len(found.unripe_clusters) == found.unripe_truth - missed
            assert found.unripe_estimate == found.unripe_truth - missed + added * missed
            assert found.estimate == found.truth  # the ripe count takes no green credit
        lone = {found.id: found.unripe_seen_once for found in counts.plants if found.unripe_seen_once}
        assert list(lone) == [plant.id] and np.linalg.norm(np.array(lone[plant.id][0]) - once) < 4 * NOISE
        assert counts.total.unripe_estimate == counts.total.unripe_truth - 1 + added


def test_an_unseen_fraction_widens_the_interval_upward(scene, all_round):
    plant = scene.plants[1]
    truth = ripe_truth(scene)[plant.id]

    def unseen(fractions: dict[int, float]) -> dict[int, PlantEvidence]:
        return {i: replace(e, unseen=fractions.get(i)) for i, e in all_round.items()}

    interval = FAST.interval.model_copy(update={"hidden_unseen": 4.0})  # a crop whose unseen canopy hides fruit
    found = from_evidence(scene, unseen({plant.id: 0.5, scene.plants[2].id: 0.0}), interval)
    half = found.plants[plant.id]
    assert half.unseen == 0.5 and half.low == half.estimate == truth < half.high
    assert found.plants[scene.plants[2].id].settled and found.plants[scene.plants[0].id].unseen is None
    whole = from_evidence(scene, unseen({plant.id: 1.0}), interval).plants[plant.id]
    assert whole.high > half.high
    assert from_evidence(scene, unseen({plant.id: 1.0}), FAST.interval).plants[plant.id].settled  # the demo's fit: 0


def test_unseen_fractions_outside_zero_to_one_or_of_no_plant_are_refused(scene):
    scan = Scan().all_sides(scene, views=3)
    with pytest.raises(UserError, match="within"):
        uncertainty(scene, scan.frames, scan.cameras, FAST, seed=0, unseen={scene.plants[0].id: 1.5})
    with pytest.raises(UserError, match="not a plant"):
        uncertainty(scene, scan.frames, scan.cameras, FAST, seed=0, unseen={999: 0.1})


# --- rows and total -------------------------------------------------------------------------------


def test_row_and_total_intervals_come_from_the_convolution_of_the_plants(scene):
    """Plants whose intervals each hold their estimate. In general a sum's interval need not: many plants each
    unlikely to hide a fruit are, together, likely to hide one (see renderloop.counting.uncertainty)."""
    scan = Scan().all_sides(scene)
    spot = empty_spot(scene, scene.plants[0])
    for camera in ring(scene.plants[0], np.radians([0.0, 4.0])):
        scan.view(camera, [spot])
    unseen = {plant.id: 0.05 * (k + 1) for k, plant in enumerate(scene.plants)}
    model = IntervalConfig(redraws=3, weak_real=0.5, hidden=0.0, hidden_per_lone=0.0, hidden_unseen=4.0)
    counting = FAST.model_copy(update={"interval": model})
    found = uncertainty(scene, scan.frames, scan.cameras, counting, seed=0, unseen=unseen)
    for row in scene.rows:
        plants = [found.plants[plant_id] for plant_id in row.plants]
        counted = found.rows[row.id]
        convolved = np.ones(1)
        for plant in plants:
            convolved = np.convolve(convolved, plant.pmf)
        np.testing.assert_allclose(counted.pmf, convolved)
        assert counted.estimate == sum(p.estimate for p in plants)
        assert counted.low <= counted.estimate <= counted.high
        assert all(p.low <= p.estimate <= p.high for p in plants)
        assert 0 < counted.width <= sum(p.width for p in plants)
    assert found.total.estimate == sum(r.estimate for r in found.rows.values())
    assert found.total.low <= found.total.estimate <= found.total.high
    assert found.total.width <= sum(p.width for p in found.plants.values())


# --- the count, counts.json and the online counter ------------------------------------------------


def test_redraw_zero_is_the_estimate_and_counts_json_keeps_the_count_of_count_rows(scene, counted_run):
    config, run = counted_run
    counts = files.read_counts(run)
    frames = files.read_detections(run, 40).frames
    [row] = count_rows(scene, class_points(frames, config.counting.eps)["ripe"], "ripe", config.counting, config.seed)  # as before intervals
    for plant in counts.plants:
        mine = row.clusters.centers[row.plants == plant.id]
        assert plant.estimate == len(mine)
        np.testing.assert_allclose(np.array(plant.clusters).reshape(-1, 3), mine, atol=1e-6)
        assert plant.interval is not None and plant.interval.level == 0.9 and plant.weak_clusters is not None
        assert plant.unseen_fraction is None  # the batch count has no voxel map
    assert counts.rows[0].interval is not None and counts.total.interval is not None
    found = uncertainty(scene, frames, {}, config.counting, config.seed)
    assert {p.id: int(p.redraw_counts[0]) for p in found.plants.values()} == {p.id: p.estimate for p in counts.plants}


def test_the_same_seed_gives_the_same_intervals_and_bytes(demo, counted_run, tmp_path: Path):
    """counts.json with its intervals, byte for byte (the online test compares two computations' distributions)."""
    config, scene = demo
    config = config.override({"counting": FAST})
    _, counted = counted_run
    again = make_run(tmp_path / "again", config, scene, synthetic_points(scene))
    run_count(again, config)
    assert (again / "counts.json").read_bytes() == (counted / "counts.json").read_bytes()


def test_counts_json_written_before_intervals_still_validates(counted_run):
    _, run = counted_run
    document = json.loads((run / "counts.json").read_text())
    for plant in document["plants"]:
        for key in ("interval", "weak_clusters", "unseen_fraction"):
            del plant[key]
    for part in (*document["rows"], document["total"]):
        del part["interval"]
    older = Counts.model_validate_json(json.dumps(document))
    assert older.plants[0].interval is None and older.total.interval is None
    assert [p.estimate for p in older.plants] == [p.estimate for p in files.read_counts(run).plants]


def test_the_online_counter_gives_the_batch_intervals(demo, tmp_path: Path):
    config, scene = demo
    config: Config = config.override({"counting": FAST})
    scan = Scan(seed=4)
    for plant in scene.plants:
        fruit = [np.array(p.center) for p in scene.peppers_of(plant.id) if p.ripe]
        for camera in ring(plant, np.radians([0.0, 15.0, 30.0, 200.0])):
            scan.view(camera, fruit)
    counter = OnlineCounter(scene, config.counting, config.seed)
    for frame in reversed(scan.frames):
        counter.add(frame, scan.cameras[frame.index])
    online = counter.uncertainty(unseen={scene.plants[0].id: 0.3})
    batch = uncertainty(scene, scan.frames, scan.cameras, config.counting, config.seed, unseen={scene.plants[0].id: 0.3})
    for plant_id, plant in batch.plants.items():
        np.testing.assert_array_equal(online.plants[plant_id].pmf, plant.pmf)
        assert online.plants[plant_id].estimate == counter.counts().per_plant().get(plant_id, 0)


def test_the_online_counter_clusters_a_row_again_only_when_its_detections_change(demo, monkeypatch):
    from renderloop.counting import cluster

    config, scene = demo
    calls = []
    original = cluster.cluster_row
    monkeypatch.setattr(cluster, "cluster_row", lambda *args: calls.append(1) or original(*args))
    scan = Scan(seed=5).all_sides(scene, views=3)
    counter = OnlineCounter(scene, FAST, config.seed)
    for frame in scan.frames:
        counter.add(frame, scan.cameras[frame.index])
    first = counter.uncertainty()
    assert len(calls) == 2 + 1  # both classes, then the ripe row's one redraw
    counter.add(DetectionFrame(index=len(scan.frames), timestamp=99.0, image="rgb/x.png", detections=[]))
    again = counter.uncertainty()
    assert len(calls) == 3  # a frame without detections changes no row
    np.testing.assert_array_equal(again.total.pmf, first.total.pmf)
    scan.view(ring(scene.plants[0], np.zeros(1))[0], [np.array(scene.peppers_of(scene.plants[0].id)[0].center)])
    counter.add(scan.frames[-1], scan.cameras[len(scan.frames) - 1])
    counter.uncertainty()
    assert len(calls) == 3 + 2  # the ripe row again, draw 0 and its redraw; the unripe row has not changed
