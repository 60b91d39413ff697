"""Two fruit whose points chain into one OPTICS cluster are split apart; one fruit is never split.

Synthetic rows of detection points (1 cm noise) around known fruit centres: a chain is a few
detections between two fruit a pepper's width apart, as views from far or boxes cut by the
image's edge put them (docs/stages/counting.md).
"""

from __future__ import annotations

import numpy as np
import pytest

from renderloop.config import CountingConfig
from renderloop.counting.cluster import cluster_row, params_from


def _fruit(rng: np.random.Generator, centre, views: int, sigma: float = 0.01) -> np.ndarray:
    return np.asarray(centre, dtype=float) + rng.normal(0.0, sigma, size=(views, 3))


def _chained_pair(rng: np.random.Generator, gap: float, views: int = 10) -> np.ndarray:
    """Two fruit `gap` apart along x, each seen `views` times, and a few detections at each third of the line between
    them (enough that a random subsample of the row keeps some)."""
    bridge = np.repeat([[gap / 3, 0.0, 1.0], [2 * gap / 3, 0.0, 1.0]], max(3, views // 20), axis=0)
    return np.vstack([_fruit(rng, (0.0, 0.0, 1.0), views), bridge, _fruit(rng, (gap, 0.0, 1.0), views)])


def _count(detections: np.ndarray, split_distance: float | None, seed: int = 0) -> np.ndarray:
    params = params_from(CountingConfig(split_distance=split_distance))
    return cluster_row(detections, params, np.random.default_rng(seed)).centers


@pytest.mark.parametrize("views", [10, 400])  # gaussian copies fill the fixed set; a random subsample of it
def test_two_fruit_a_pepper_apart_whose_points_chain_are_counted_as_two(views):
    rng = np.random.default_rng(1)
    detections = _chained_pair(rng, 0.1, views)
    assert len(_count(detections, None)) == 1  # the paper's rule: one cluster, one fruit
    centres = _count(detections, 0.07)
    assert len(centres) == 2
    found = np.sort(centres[:, 0])
    np.testing.assert_allclose(found, [0.0, 0.1], atol=0.015)


def test_three_fruit_in_a_chain_are_counted_as_three():
    rng = np.random.default_rng(2)
    chain = np.vstack([_chained_pair(rng, 0.1), _chained_pair(rng, 0.1) + [0.1, 0.0, 0.0]])
    assert len(_count(chain, None)) == 1
    assert len(_count(chain, 0.07)) == 3


def test_one_fruit_is_never_split_however_its_points_spread():
    rng = np.random.default_rng(3)
    for seed in range(5):
        spread = _fruit(rng, (0.0, 0.0, 1.0), 60, sigma=0.015)  # points of a fruit seen from every side
        assert len(_count(spread, 0.07, seed)) == 1
    stray = np.vstack([_fruit(rng, (0.0, 0.0, 1.0), 20), [[0.035, 0.0, 1.0], [0.07, 0.0, 1.0]]])
    assert len(_count(stray, 0.07)) == 1  # a part of one stray detection is no fruit: each part needs min_views


def test_the_split_does_not_depend_on_the_order_of_the_detections():
    rng = np.random.default_rng(4)
    detections = _chained_pair(rng, 0.11)
    first = _count(detections, 0.07)
    shuffled = _count(detections[rng.permutation(len(detections))], 0.07)
    np.testing.assert_allclose(np.sort(first, axis=0), np.sort(shuffled, axis=0), atol=1e-9)


def test_the_default_counting_splits_and_null_keeps_the_papers_rule():
    assert params_from(CountingConfig()).split_distance == 0.07
    assert params_from(CountingConfig(split_distance=None)).split_distance is None
