"""`renderloop threshold RUN_DIR...`: the detector's score threshold, chosen on rendered runs it never trained on.

The rule the shipped default was chosen by: the lowest score at which at most `max_false`
of the scored detections are false (docs/stages/perception.md). Fused scores run higher the more
passes search a frame, so a new model, other windows or the mirror turned off each need the
threshold chosen again. Every frame is searched once, keeping its fused boxes down to
PASS_FLOOR; a higher threshold only drops boxes, so each candidate is scored on exactly the
detections `renderloop detect --threshold t` would give, against the masks. The rule serves
the detection goal; counting can want fewer false boxes than it allows, so check the counts
at a threshold it chooses (docs/stages/perception.md).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from renderloop.config import DetectorConfig
from renderloop.perception.detector import PASS_FLOOR, Detector
from renderloop.perception.scoring import FrameTruth, RunScore
from renderloop.render.frames import read_png, read_rgb_frame
from renderloop.rundir import files, names
from renderloop.scene.model import Scene, read_scene

# Every 0.01 from the floor (below it the search keeps no fused box) to 0.99, then every 0.001: a model trained with a
# low match IoU (`train --match-iou`) scores its boxes so near 1 that the 5 % rule's threshold can lie above 0.99.
THRESHOLDS = (tuple(round(t, 2) for t in np.arange(PASS_FLOOR, 0.995, 0.01))
              + tuple(round(t, 3) for t in np.arange(0.991, 0.9995, 0.001)))


def threshold_text(threshold: float) -> str:
    """A threshold as it is set: two decimals on the 0.01 grid (0.68), three above 0.99 (0.992)."""
    return f"{threshold:.2f}" if round(threshold, 2) == threshold else f"{threshold:.3f}"

Progress = Callable[[int, int], None]
NEEDS = (names.SCENE, names.POSES, names.frames_index(names.RGB))  # what the search reads: a rendered run


@dataclass(frozen=True)
class ThresholdScore:
    threshold: float
    found: int  # findable ripe fruit matched
    findable: int
    false: int
    detections: int  # scored detections (boxes on fruit too small to count are ignored)

    @property
    def recall(self) -> float:
        return self.found / self.findable if self.findable else 0.0

    @property
    def false_rate(self) -> float:
        return self.false / self.detections if self.detections else 0.0


@dataclass(frozen=True)
class SearchedRun:
    """One run's frames searched at the floor: the detections and the mask's boxes of each frame."""
    scene: Scene
    frames: list[tuple[list[dict], FrameTruth]]


def search_run(run_dir: Path, detector: Detector, settings: DetectorConfig, progress: Progress | None = None) -> SearchedRun:
    """Every frame's detections down to PASS_FLOOR, with the windows and mirror of `settings` (its threshold is what
    the search chooses), and the frame's truth."""
    run_dir = Path(run_dir)
    files.require(run_dir, NEEDS)
    scene = read_scene(run_dir)
    frames = []
    count = len(files.read_poses(run_dir)[0])
    for index in range(count):
        if progress:
            progress(index, count)
        # boxes as detections.json stores them, scores unrounded: `detect` compares the unrounded score with its threshold
        found = [{**d.to_json(), "score": d.score}
                 for d in detector.search(read_rgb_frame(run_dir, index), settings, PASS_FLOOR)]
        frames.append((found, FrameTruth.of_mask(read_png(run_dir / names.frame_file(names.MASKS, index), np.uint16))))
    return SearchedRun(scene, frames)


def score_thresholds(runs: Sequence[SearchedRun], thresholds: Sequence[float] = THRESHOLDS) -> list[ThresholdScore]:
    """Recall and false detections of all runs together at each threshold (each at least PASS_FLOOR)."""
    scores = []
    for threshold in thresholds:
        totals = np.zeros(4, dtype=int)
        for run in runs:
            score = RunScore.of_scene(run.scene)
            for detections, truth in run.frames:
                score.add_truth([d for d in detections if d["score"] >= threshold], truth)
            totals += (score.found_ripe, score.findable_ripe, score.false, score.detections)
        scores.append(ThresholdScore(float(threshold), *(int(v) for v in totals)))
    return scores


def choose(scores: Sequence[ThresholdScore], max_false: float) -> ThresholdScore | None:
    """The lowest threshold with at most `max_false` false detections, or None when none has so few
    (a threshold that lets no detection through has none false, but finds nothing either)."""
    return next((s for s in sorted(scores, key=lambda s: s.threshold) if s.detections and s.false_rate <= max_false), None)


def format_scores(scores: Sequence[ThresholdScore], chosen: ThresholdScore | None) -> str:
    """Every 0.05 of the sweep, its last threshold and the chosen one, as a table."""
    shown = [s for s in scores if round(s.threshold * 1000) % 50 == 0 or s == chosen or s == scores[-1]]
    lines = [f"{'score':>6} {'ripe recall':>12} {'found':>12} {'false':>7} {'false boxes':>12}"]
    for s in shown:
        mark = "  <- chosen" if s == chosen else ""
        lines.append(f"{threshold_text(s.threshold):>6} {s.recall:>12.3f} {f'{s.found}/{s.findable}':>12} {s.false_rate:>7.1%} "
                     f"{f'{s.false}/{s.detections}':>12}{mark}")
    return "\n".join(lines)
