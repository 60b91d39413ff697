"""Which fruit the scan showed at all: from the instance masks, per fruit, the frames with visible pixels and the
largest visible box. A fruit no frame showed is the scan's miss, not the detector's; one only ever seen smaller than
the detector's findable size (perception.scoring.MIN_SIDE) is the camera's."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from renderloop.perception.scoring import findable, mask_boxes
from renderloop.render.frames import read_png
from renderloop.rundir import names


@dataclass(frozen=True)
class Seen:
    frames: int  # frames in which the fruit has visible pixels
    largest: tuple[int, int]  # width and height of its largest visible box, px

    @property
    def findable(self) -> bool:
        return findable((0, 0, *self.largest))


def fruit_visibility(run_dir: Path, frame_count: int) -> dict[int, Seen] | None:
    """Pepper id -> how the scan saw it; None when the run has no masks for every frame (counted from detections alone)."""
    paths = [Path(run_dir) / names.frame_file(names.MASKS, index) for index in range(frame_count)]
    if not all(path.is_file() for path in paths):
        return None
    frames: dict[int, int] = {}
    largest: dict[int, tuple[int, int]] = {}
    for path in paths:
        for pepper, (x0, y0, x1, y1) in mask_boxes(read_png(path, np.uint16)).items():
            frames[pepper] = frames.get(pepper, 0) + 1
            best = largest.get(pepper, (0, 0))
            largest[pepper] = max(best, (x1 - x0, y1 - y0), key=lambda size: size[0] * size[1])
    return {pepper: Seen(frames[pepper], largest[pepper]) for pepper in frames}
