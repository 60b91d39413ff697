"""The paper's per-row counting, kept up to date while the robot flies.

Detections are added frame by frame as perception finishes them; `counts()` clusters what
has been added so far with exactly the rules and seeds of `renderloop count`, so once every
frame is in, the online count is the batch count. Each counted fruit carries its support:
how many detections (views) its cluster holds, which mission logic reads as confidence.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderloop.config import CountingConfig
from renderloop.counting.cluster import CLASSES, RowCount, class_points, count_rows
from renderloop.rundir.models import DetectionFrame
from renderloop.scene.model import Scene


@dataclass(frozen=True)
class CountedFruit:
    plant: int
    label: str  # ripe or unripe
    center: np.ndarray  # world frame, m
    support: int  # detections (views) in its cluster


@dataclass(frozen=True)
class OnlineCount:
    frames: int  # frames whose detections are in
    fruit: list[CountedFruit]

    def per_plant(self, label: str = "ripe") -> dict[int, int]:
        counts: dict[int, int] = {}
        for fruit in self.fruit:
            if fruit.label == label:
                counts[fruit.plant] = counts.get(fruit.plant, 0) + 1
        return counts

    def total(self, label: str = "ripe") -> int:
        return sum(fruit.label == label for fruit in self.fruit)


def _support(row: RowCount) -> list[int]:
    """Detections (not augmented copies) in each cluster of a row, in cluster order."""
    clusters = row.clusters
    return [int(np.count_nonzero(clusters.original & (clusters.labels == k))) for k in range(len(clusters.centers))]


class OnlineCounter:
    def __init__(self, scene: Scene, counting: CountingConfig, seed: int) -> None:
        self.scene, self.counting, self.seed = scene, counting, seed
        self.frames: dict[int, DetectionFrame] = {}
        self._last: OnlineCount | None = None

    def add(self, frame: DetectionFrame) -> None:
        self.frames[frame.index] = frame
        self._last = None

    def rows(self) -> dict[str, list[RowCount]]:
        """Each class counted per row, on the points of the frames in order (as the batch count reads them)."""
        points = class_points(self.frames[index] for index in sorted(self.frames))
        return {label: count_rows(self.scene, points[label], label, self.counting, self.seed) for label in CLASSES}

    def counts(self) -> OnlineCount:
        """What the counting makes of the detections added so far."""
        if self._last is None:
            fruit = []
            for label, rows in self.rows().items():
                for row in rows:
                    for plant, center, support in zip(row.plants, row.clusters.centers, _support(row)):
                        fruit.append(CountedFruit(int(plant), label, np.asarray(center), support))
            self._last = OnlineCount(len(self.frames), fruit)
        return self._last
