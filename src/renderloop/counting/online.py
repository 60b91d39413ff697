"""The paper's per-row counting, kept up to date while the robot flies.

Detections are added frame by frame as perception finishes them; `counts()` clusters what
has been added so far with exactly the rules and seeds of `renderloop count`, so once every
frame is in, the online count is the batch count. Each counted fruit carries its support:
how many detections (views) its cluster holds; `uncertainty()` gives each plant's count
interval (`renderloop.counting.uncertainty`), which mission logic reads as confidence.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from renderloop.config import CountingConfig
from renderloop.counting.cluster import (
    CLASSES,
    RowCount,
    RowMemo,
    class_points,
    count_rows,
)
from renderloop.counting.uncertainty import LABEL, Uncertainty, uncertainty
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


class OnlineCounter:
    def __init__(self, scene: Scene, counting: CountingConfig, seed: int) -> None:
        self.scene, self.counting, self.seed = scene, counting, seed
        self.frames: dict[int, DetectionFrame] = {}
        self.camera_positions: dict[int, np.ndarray] = {}  # frame index -> camera position in the world, m
        self._rows: dict[str, list[RowCount]] | None = None
        self._last: OnlineCount | None = None
        self._memo: RowMemo = {}  # each row's last clusterings: asked again, only changed rows are counted again

    def add(self, frame: DetectionFrame, camera_position: np.ndarray | None = None) -> None:
        """A frame's detections; with the camera's position (world, m), the uncertainty also knows which sides
        each fruit was seen from."""
        self.frames[frame.index] = frame
        if camera_position is not None:
            self.camera_positions[frame.index] = np.asarray(camera_position, dtype=float).reshape(3)
        self._rows = self._last = None

    def _ordered(self) -> list[DetectionFrame]:
        return [self.frames[index] for index in sorted(self.frames)]

    def rows(self) -> dict[str, list[RowCount]]:
        """Each class counted per row, on the points of the frames in order (as the batch count reads them)."""
        if self._rows is None:
            points = class_points(self._ordered(), self.counting.eps)
            self._rows = {label: count_rows(self.scene, points[label], label, self.counting, self.seed, memo=self._memo)
                          for label in CLASSES}
        return self._rows

    def uncertainty(self, unseen: Mapping[int, float | None] | None = None,
                    model: CountingConfig | None = None) -> Uncertainty:
        """Each plant's, row's and the total ripe count with its interval, from the frames added so far; `unseen`:
        plant id -> share of its canopy box no depth frame has seen; `model`: the counter's settings with another
        interval and lone credit (an adaptive run's count, `run_counting`). Costs `counting.interval.redraws` - 1
        recounts of the ripe rows whose detections changed since the last call."""
        counting = self.counting if model is None else self.counting.model_copy(
            update={"interval": model.interval, "lone_credit": model.lone_credit})
        return uncertainty(self.scene, self._ordered(), self.camera_positions, counting, self.seed, unseen,
                           estimate=self.rows()[LABEL], memo=self._memo)

    def counts(self) -> OnlineCount:
        """What the counting makes of the detections added so far."""
        if self._last is None:
            fruit = []
            for label, rows in self.rows().items():
                for row in rows:
                    for plant, center, support in zip(row.plants, row.clusters.centers, row.clusters.support()):
                        fruit.append(CountedFruit(int(plant), label, np.asarray(center), int(support)))
            self._last = OnlineCount(len(self.frames), fruit)
        return self._last
