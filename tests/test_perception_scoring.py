"""Scoring detections against instance masks: what is a hit, what is false, what is ignored."""

import numpy as np
import pytest

from renderloop.perception.boxes import box_iou
from renderloop.perception.scoring import FrameTruth, RunScore, match, shares_inside
from renderloop.scene.model import NEIGHBOUR_FRUIT_ID

RIPE_BIG, RIPE_SMALL, UNRIPE_BIG = 1, 2, 3


def _mask() -> np.ndarray:
    mask = np.zeros((120, 160), dtype=np.uint16)
    mask[10:50, 10:50] = RIPE_BIG  # 40 x 40: findable
    mask[80:92, 100:112] = RIPE_SMALL  # 12 x 12: under the 20 px rule
    mask[60:100, 20:60] = UNRIPE_BIG
    mask[10:40, 120:150] = NEIGHBOUR_FRUIT_ID  # a neighbouring row's fruit, cut in two by a string at column 134
    mask[:, 134] = 0
    return mask


def _score(*boxes: list[float], label: str = "ripe") -> dict:
    score = RunScore({RIPE_BIG: True, RIPE_SMALL: True, UNRIPE_BIG: False}, {})
    score.add([{"bbox": list(box), "score": 0.9 - 0.01 * i, "label": label} for i, box in enumerate(boxes)], _mask())
    return score.summary()


def test_a_box_on_a_findable_pepper_is_a_hit_and_a_box_on_nothing_is_false() -> None:
    summary = _score([11, 9, 50, 49], [120, 60, 150, 90])
    assert (summary["ripe_findable"], summary["ripe_found"]) == (1, 1)
    assert (summary["detections_scored"], summary["false_detections"]) == (2, 1)


def test_a_second_box_on_a_found_pepper_is_false() -> None:
    summary = _score([10, 10, 50, 50], [12, 12, 48, 48])
    assert summary["ripe_found"] == 1 and summary["false_detections"] == 1


def test_a_partial_box_on_a_findable_pepper_is_false() -> None:
    summary = _score([10, 10, 30, 30])  # inside the pepper, IoU 0.25
    assert summary["ripe_found"] == 0 and summary["false_detections"] == 1


def test_a_box_on_a_pepper_too_small_to_count_is_ignored_even_off_by_a_few_pixels() -> None:
    summary = _score([103, 83, 114, 94])  # IoU 0.44 with the 12 px pepper, two thirds of the box on it
    assert summary["detections_scored"] == 0 and summary["false_detections"] == 0
    assert summary["ripe_findable"] == 1 and summary["ripe_found"] == 0


def test_a_box_mostly_off_a_small_pepper_is_false() -> None:
    summary = _score([104, 86, 124, 106])  # an eighth of it on the small pepper
    assert summary["false_detections"] == 1


def test_the_other_class_still_finds_the_fruit_and_is_scored_as_a_wrong_label() -> None:
    summary = _score([10, 10, 50, 50], label="unripe")
    assert summary["ripe_found"] == 1 and summary["false_detections"] == 0 and summary["label_accuracy"] == 0.0


def test_matching_takes_detections_by_score_each_to_its_most_overlapping_free_pepper() -> None:
    def greedy(detections, truth):  # the rule written plainly: one detection and one pepper at a time
        matched = {}
        for d in sorted(range(len(detections)), key=lambda d: -detections[d]["score"]):
            free = [(box_iou(np.array([detections[d]["bbox"]], float), np.array([box], float))[0, 0], -k, pepper)
                    for k, (pepper, box) in enumerate(truth.items()) if pepper not in matched.values()]
            best = max(free, default=None)
            if best is not None and best[0] >= 0.5:
                matched[d] = best[2]
        return matched

    rng = np.random.default_rng(0)
    for _ in range(200):
        corners = rng.integers(0, 40, (12, 2))
        truth = {10 + k: (int(x), int(y), int(x) + 12, int(y) + 12) for k, (x, y) in enumerate(corners[:4])}
        detections = [{"bbox": [int(x), int(y), int(x) + int(rng.integers(9, 15)), int(y) + 12],
                       "score": float(rng.choice([0.5, 0.7, 0.9]))} for x, y in corners[4:]]
        assert match(detections, truth) == greedy(detections, truth)


def test_shares_inside_are_each_boxs_largest_covered_share() -> None:
    boxes = np.array([[0, 0, 10, 10], [0, 0, 10, 10], [30, 30, 40, 40]], dtype=float)
    assert shares_inside(boxes, []).tolist() == [0.0, 0.0, 0.0]
    assert shares_inside(boxes[:1], [(5, 0, 20, 10), (0, 0, 10, 2)]) == pytest.approx([0.5])
    assert shares_inside(boxes, [(-5, -5, 15, 15)]) == pytest.approx([1.0, 1.0, 0.0])
    assert shares_inside(np.zeros((0, 4)), [(0, 0, 1, 1)]).shape == (0,)


def test_a_box_on_a_neighbouring_rows_fruit_is_neither_a_hit_nor_false_and_a_box_mostly_off_it_is_false() -> None:
    truth = FrameTruth.of_mask(_mask())
    assert truth.neighbours == [(120, 10, 150, 40)] and NEIGHBOUR_FRUIT_ID not in truth.peppers  # one fruit, string and all
    summary = _score([121, 11, 149, 41])
    assert summary["detections_scored"] == 0 and summary["false_detections"] == 0
    summary = _score([140, 30, 160, 60])  # a sixth of it on the fruit
    assert summary["detections_scored"] == 1 and summary["false_detections"] == 1
