"""The vectorised 2-opt of the harvest plan against the pair-by-pair scan it replaces.

`two_opt_pair_by_pair` is that scan written out plainly (one reversal tested at a time,
with numpy's norm of each leg): the vectorised `two_opt` must apply the same moves in the same
order, so it returns the same tour, and the presets' harvest plans stay the same bytes.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import scene_for

from renderloop.config import load_config
from renderloop.counting import harvest
from renderloop.counting.harvest import (
    IMPROVEMENT,
    nearest_neighbour,
    plan_harvest,
    tour_length,
    two_opt,
    two_opt_pair_by_pair,
)
from renderloop.io.atomic import dumps_json


def instance(seed: int, size: int) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Stops in a 20 m square with the workstation among them; every third instance on the 6 x 6 points of
    integer coordinates, where reversals tie and stops coincide; the starting tour greedy, or every fourth
    one a random order."""
    rng = np.random.default_rng(seed)
    stops, start = rng.uniform(0.0, 20.0, size=(size, 2)), rng.uniform(0.0, 20.0, size=2)
    if seed % 3 == 0:
        stops, start = np.round(stops / 4.0), np.round(start / 4.0)
    order = [int(k) for k in rng.permutation(size)] if seed % 4 == 0 else nearest_neighbour(start, stops)
    return start, stops, order


def best_single_reversal_gain(start: np.ndarray, stops: np.ndarray, order: list[int]) -> float:
    """How much the best single segment reversal shortens the closed tour (m), every (i, j) at once."""
    path = np.vstack([start, stops[order], start])
    i, j = np.triu_indices(len(path) - 1, k=1)
    keep = (i >= 1) & (j <= len(path) - 2)
    i, j = i[keep], j[keep]

    def leg(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        return np.linalg.norm(path[p] - path[q], axis=1)

    gains = leg(i - 1, i) + leg(j, j + 1) - leg(i - 1, j) - leg(i, j + 1)
    return float(gains.max()) if gains.size else 0.0


def test_two_opt_returns_the_pair_by_pair_scans_tour_on_many_random_instances():
    sizes = []
    for seed in range(240):
        size = 5 + seed * 37 % 56  # 5 .. 60 stops
        start, stops, order = instance(seed, size)
        assert two_opt(start, stops, order) == two_opt_pair_by_pair(start, stops, order), f"seed {seed}, {size} stops"
        sizes.append(size)
    assert min(sizes) == 5 and max(sizes) == 60


@pytest.mark.parametrize("size", [0, 1, 2, 3])
def test_two_opt_handles_tours_too_short_to_reverse(size: int):
    start, stops, order = instance(1, size)
    assert two_opt(start, stops, order) == two_opt_pair_by_pair(start, stops, order)
    assert sorted(two_opt(start, stops, order)) == list(range(size))


@pytest.mark.parametrize("seed, size", [(1, 30), (2, 120), (3, 120), (5, 400)])
def test_the_tour_is_two_opt_optimal(seed: int, size: int):
    start, stops, greedy = instance(seed, size)
    order = two_opt(start, stops, greedy)
    assert sorted(order) == list(range(size))
    assert tour_length(start, stops, order) <= tour_length(start, stops, greedy) + 1e-9
    # recomputed independently (row norms, not the search's arithmetic): allow for last-bit rounding only
    assert best_single_reversal_gain(start, stops, order) <= IMPROVEMENT + 1e-12


def test_a_reversal_shortening_the_tour_by_less_than_the_tolerance_is_not_taken():
    start = np.array([0.0, 0.0])
    # out along the x axis and straight back, the first stop lifted by `lift`: visiting the last two
    # stops the other way round shortens the tour by lift^2 / 4
    for lift, expected in ((4e-5, [0, 1, 2]), (8e-5, [0, 2, 1])):
        stops = np.array([[1.0, lift], [2.0, 0.0], [3.0, 0.0]])
        gain = tour_length(start, stops, [0, 1, 2]) - tour_length(start, stops, [0, 2, 1])
        assert gain == pytest.approx(lift**2 / 4, rel=1e-3)
        assert two_opt(start, stops, [0, 1, 2]) == two_opt_pair_by_pair(start, stops, [0, 1, 2]) == expected


@pytest.mark.parametrize("preset", ["demo", "paper", "greenhouse"])
def test_the_presets_harvest_plans_are_the_same_bytes_as_with_the_pair_by_pair_scan(preset: str, monkeypatch):
    config, scene = scene_for(preset, load_config(preset).seed)
    ripe = {plant.id: sum(1 for pepper in scene.peppers_of(plant.id) if pepper.ripe) for plant in scene.plants}
    plans = {min_ripe: dumps_json(plan_harvest(scene, ripe, min_ripe)) for min_ripe in range(max(ripe.values()) + 2)}
    monkeypatch.setattr(harvest, "two_opt", two_opt_pair_by_pair)
    for min_ripe, plan in plans.items():
        assert plan == dumps_json(plan_harvest(scene, ripe, min_ripe)), f"{preset}, min_ripe {min_ripe}"
    assert config.counting.harvest_min_ripe in plans

