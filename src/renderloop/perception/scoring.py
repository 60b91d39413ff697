"""Detections against the truth of a rendered run: boxes from the instance masks, IoU matching, 3D error.

A pepper counts as findable when its visible part spans at least MIN_SIDE x MIN_SIDE
pixels (the issue's 20 x 20 at 640 x 480). Matching is greedy by score at IoU 0.5,
one detection per pepper; a detection of the other class still counts as the fruit
found (ripeness is scored separately, as label accuracy).

Peppers too small to count are ignore regions, as COCO's `iscrowd` boxes are (and as
`renderloop dataset` marks its tiniest fruit): a detection that matches one at IoU 0.5,
or lies on one (at least half of the detection's box inside the pepper's), is neither
a hit nor a false detection. IoU alone would call a box on a 12 px pepper false for a
3 px offset, though it found a real pepper that the recall does not ask for.

The neighbouring rows' fruit are ignore regions too: real peppers, seen under and
through the scanned canopy, that no count asks for. The masks mark them all with one
id (`NEIGHBOUR_FRUIT_ID`), so each connected patch of it, small gaps closed (a string
or a leaf's edge across a fruit), is one region.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from renderloop.perception.boxes import box_area, box_iou, intersection, shorter_side
from renderloop.rundir.models import DetectionFrame, DetectionScores
from renderloop.scene.model import NEIGHBOUR_FRUIT_ID, Scene

MIN_SIDE = 20
MATCH_IOU = 0.5
IGNORE_COVER = 0.5  # share of a detection's box on an ignored pepper that makes it ignored (COCO's crowd rule)
NEIGHBOUR_GAP = 2  # px: gaps this wide in a neighbouring fruit's pixels are closed before its patches are found

Box = tuple[int, int, int, int]


def mask_boxes(mask: np.ndarray) -> dict[int, Box]:
    """Pepper id -> box of its visible pixels (x0, y0, x1, y1; x1, y1 one past the last pixel)."""
    ids = np.unique(mask)
    boxes = {}
    for pepper_id in ids[(ids > 0) & (ids != NEIGHBOUR_FRUIT_ID)].tolist():
        rows, cols = np.nonzero(mask == pepper_id)
        boxes[pepper_id] = (int(cols.min()), int(rows.min()), int(cols.max()) + 1, int(rows.max()) + 1)
    return boxes


def neighbour_boxes(mask: np.ndarray) -> list[Box]:
    """Boxes of the neighbouring rows' fruit in `mask`: one per connected patch, gaps of NEIGHBOUR_GAP px closed."""
    fruit = mask == NEIGHBOUR_FRUIT_ID
    if not fruit.any():
        return []
    closed = ndimage.binary_closing(np.pad(fruit, NEIGHBOUR_GAP), iterations=NEIGHBOUR_GAP)[
        NEIGHBOUR_GAP:-NEIGHBOUR_GAP, NEIGHBOUR_GAP:-NEIGHBOUR_GAP] | fruit
    patches = ndimage.find_objects(ndimage.label(closed)[0])
    return [(cols.start, rows.start, cols.stop, rows.stop) for rows, cols in patches]


@dataclass(frozen=True)
class FrameTruth:
    """What one frame's mask says: the boxes of the scene's peppers and of the neighbouring rows' fruit."""

    peppers: dict[int, Box]
    neighbours: list[Box]

    @classmethod
    def of_mask(cls, mask: np.ndarray) -> FrameTruth:
        return cls(mask_boxes(mask), neighbour_boxes(mask))


def match(detections: list[dict], truth: dict[int, tuple[int, int, int, int]]) -> dict[int, int]:
    """Detection index -> pepper id, greedy by decreasing score at IoU >= 0.5: each detection takes the free pepper it
    overlaps most (the first of equals)."""
    if not detections or not truth:
        return {}
    ids = list(truth)
    iou = box_iou(np.array([d["bbox"] for d in detections], dtype=float), np.array([truth[i] for i in ids], dtype=float))
    overlaps = iou >= MATCH_IOU
    reaching = overlaps.any(axis=1)
    taken = np.zeros(len(ids), dtype=bool)
    matched: dict[int, int] = {}
    for d in np.argsort([-d["score"] for d in detections], kind="stable"):
        if not reaching[d]:
            continue
        free = overlaps[d] & ~taken
        if free.any():
            j = int(np.argmax(np.where(free, iou[d], -1.0)))
            taken[j] = True
            matched[int(d)] = ids[j]
    return matched


def findable(box: tuple[int, int, int, int]) -> bool:
    return shorter_side(box) >= MIN_SIDE


def shares_inside(boxes: np.ndarray, regions: list[tuple[int, int, int, int]]) -> np.ndarray:
    """(N,): the largest share of each box's area (boxes (N, 4)) that lies inside one of `regions` (0 with none)."""
    if not regions or not len(boxes):
        return np.zeros(len(boxes))
    inside = intersection(boxes, np.asarray(regions, dtype=float)).max(axis=1)
    return inside / np.maximum(box_area(boxes), np.finfo(float).tiny)


class RunScore:
    """Accumulates frame by frame; `summary()` gives the figures of the perception issue."""

    def __init__(self, ripe: dict[int, bool], centers: dict[int, np.ndarray]) -> None:
        self.ripe, self.centers = ripe, centers
        self.findable_ripe = self.found_ripe = self.detections = self.false = self.label_right = self.labelled = 0
        self.errors: list[float] = []

    @classmethod
    def of_scene(cls, scene) -> RunScore:
        return cls({p.id: p.ripe for p in scene.peppers}, {p.id: np.asarray(p.center) for p in scene.peppers})

    def add(self, detections: list[dict], mask: np.ndarray) -> None:
        self.add_truth(detections, FrameTruth.of_mask(mask))

    def add_truth(self, detections: list[dict], frame: FrameTruth) -> None:
        """`add` with the mask read already: scoring one frame at many thresholds reads its mask once."""
        truth = frame.peppers
        matched = match(detections, truth)
        ignored = [box for box in truth.values() if not findable(box)] + frame.neighbours
        unmatched = [index for index in range(len(detections)) if index not in matched]
        on_ignored = set()
        if ignored and unmatched:  # all of a frame's boxes at once: the threshold search scores thousands of frames
            shares = shares_inside(np.array([detections[i]["bbox"] for i in unmatched], dtype=float), ignored)
            on_ignored = {index for index, share in zip(unmatched, shares) if share >= IGNORE_COVER}
        for index, detection in enumerate(detections):
            pepper = matched.get(index)
            if pepper is None:
                if index in on_ignored:
                    continue
                self.detections += 1
                self.false += 1
                continue
            if not findable(truth[pepper]):
                continue
            self.detections += 1
            self.labelled += 1
            self.label_right += (detection["label"] == "ripe") == self.ripe[pepper]
            if detection.get("position") is not None:
                self.errors.append(float(np.linalg.norm(np.asarray(detection["position"]) - self.centers[pepper])))
        hits = set(matched.values())
        for pepper, box in truth.items():
            if self.ripe[pepper] and findable(box):
                self.findable_ripe += 1
                self.found_ripe += pepper in hits

    def summary(self) -> dict:
        def ratio(a: int, b: int) -> float | None:
            return round(a / b, 4) if b else None

        return {
            "ripe_findable": self.findable_ripe, "ripe_found": self.found_ripe,
            "ripe_recall": ratio(self.found_ripe, self.findable_ripe),
            "detections_scored": self.detections, "false_detections": self.false,
            "false_rate": ratio(self.false, self.detections),
            "label_accuracy": ratio(self.label_right, self.labelled),
            "position_error_median_m": round(float(np.median(self.errors)), 4) if self.errors else None,
            "position_error_p90_m": round(float(np.percentile(self.errors, 90)), 4) if self.errors else None,
        }


def score_frames(scene: Scene, frames: list[DetectionFrame], masks: Iterable[np.ndarray]) -> DetectionScores:
    """A run's detections against its instance masks, one mask per frame in the order of `frames`."""
    score = RunScore.of_scene(scene)
    for frame, mask in zip(frames, masks, strict=True):
        score.add([d.model_dump() for d in frame.detections], mask)
    return DetectionScores(**score.summary())
