"""Merging the boxes of several detector passes: agreement between passes adds up, duplicates within one do not."""

import numpy as np

from renderloop.perception.fusion import fuse


def fused(boxes: list[tuple[float, ...]], scores: list[float], passes: list[int]) -> list[tuple[int, float]]:
    leaders, merged = fuse(np.array(boxes, dtype=float), np.array(scores), np.array(passes))
    return [(int(k), round(float(s), 9)) for k, s in zip(leaders, merged, strict=True)]


def test_boxes_of_one_fruit_from_several_passes_add_up_as_a_noisy_or() -> None:
    fruit = [(10.0, 10.0, 40.0, 50.0), (12.0, 11.0, 41.0, 48.0), (9.0, 12.0, 39.0, 52.0)]
    assert fused(fruit, [0.4, 0.45, 0.3], [0, 1, 2]) == [(1, round(1 - 0.6 * 0.55 * 0.7, 9))]


def test_a_second_box_of_the_same_pass_is_a_duplicate_not_a_second_opinion() -> None:
    fruit = [(10.0, 10.0, 40.0, 50.0), (12.0, 11.0, 41.0, 48.0), (11.0, 10.0, 40.0, 49.0)]
    assert fused(fruit, [0.4, 0.45, 0.3], [0, 1, 1]) == [(1, round(1 - 0.6 * 0.55, 9))]


def test_apart_boxes_stay_apart_with_their_own_scores_best_first() -> None:
    boxes = [(0.0, 0.0, 20.0, 20.0), (100.0, 100.0, 130.0, 120.0), (15.0, 0.0, 35.0, 20.0)]  # IoU of 1st and 3rd: 1/7
    assert fused(boxes, [0.5, 0.9, 0.6], [0, 0, 1]) == [(1, 0.9), (2, 0.6), (0, 0.5)]


def test_the_best_box_leads_its_group_whichever_pass_found_it() -> None:
    boxes = [(0.0, 0.0, 30.0, 30.0), (1.0, 0.0, 31.0, 30.0), (50.0, 50.0, 60.0, 60.0)]
    leaders, merged = fuse(np.array(boxes), np.array([0.3, 0.8, 0.2]), np.array([1, 0, 0]))
    assert leaders.tolist() == [1, 2] and np.allclose(merged, [1 - 0.7 * 0.2, 0.2])


def test_nothing_to_fuse_gives_nothing() -> None:
    leaders, merged = fuse(np.zeros((0, 4)), np.zeros(0), np.zeros(0, dtype=int))
    assert leaders.size == 0 and merged.size == 0
