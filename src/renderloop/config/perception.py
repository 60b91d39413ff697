"""The detector and the count (`detector`, `counting`)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field

from renderloop.config.fields import Count, Fraction, Real, Strict

Layout = tuple[int, int]  # a window layout (perception/tiling.py): columns, rows
LAYOUT_PATTERN = r"[1-8]x[1-8]"
MAX_ENLARGEMENT = 1.5  # detector.max_window_enlargement's default


def layout(text: str) -> Layout:
    columns, rows = text.split("x")
    return int(columns), int(rows)


class DetectorConfig(Strict):
    model: Path | None = Field(None, description="ONNX model; null means the one shipped in the package.")
    score_threshold: Fraction = Field(0.88, description="Score a detection needs. Fused scores run higher than one "
                                      "pass's; the default is the lowest at which at most 5 % of the shipped model's "
                                      "detections on held-out paper runs are false, with the default windows and "
                                      "mirror (`renderloop threshold`, docs/stages/perception.md).")
    windows: tuple[Annotated[str, Field(pattern=f"^{LAYOUT_PATTERN}$")], ...] = Field(
        ("2x2",), max_length=64,  # the 8 x 8 possible layouts
        description="Also search the overlapping windows of these columns x rows layouts of each frame, "
        "where small fruit look larger (one network pass a window; perception/tiling.py); []: the whole frame only.")
    max_window_enlargement: Real(1.0, 16.0) = Field(
        MAX_ENLARGEMENT, description="Most times the network's input may enlarge a window, on either side, for its "
        "layout to be searched. At 1.5 a 640x480 frame takes the 2x2 windows and a 320x240 frame none; a larger "
        "enlargement shows no pixel the frame does not, but it is one more look, which the greenhouse preset's "
        "320x240 frames gain from at 3 (perception/tiling.py, docs/stages/perception.md).")
    mirror: bool = Field(True, description="Also search the frame mirrored left to right, the passes fused: one more "
                         "network pass, for recall at the same rate of false detections (docs/stages/perception.md).")
    min_box_px: Real(0.0, 10_000.0) = Field(
        0.0, description="Shorter side a detection's box needs, px of the frame; 0 keeps every box. A box under 10 px "
        "cannot match a findable fruit (20 px or more a side, perception/scoring.py) at IoU 0.5, so what it holds is "
        "smaller fruit or no fruit (docs/stages/perception.md).")

    @property
    def layouts(self) -> list[Layout]:
        return [layout(text) for text in self.windows]


class IntervalConfig(Strict):
    """The interval of each plant's ripe count (renderloop.counting.uncertainty): every counted cluster is a real
    fruit (weak ones with probability `weak_real`), plus hidden fruit ~ Poisson(hidden + hidden_per_lone x lone
    detections + hidden_unseen x unseen fraction), mixed over redraws of the random fixed set. All four are fitted by
    benchmarks/intervals.py on demo runs; the greenhouse preset has its own fit (docs/stages/counting.md)."""

    level: Real(0.5, 0.999) = Field(0.9, description="Probability the interval holds the true count (its central quantiles).")
    redraws: Count(1, 64) = Field(
        8, description="Counts of each row the interval mixes: the estimate and redraws - 1 redraws of the random fixed "
        "set, each costing as much as counting the ripe rows again.")
    weak_margin: Real(1.0, 100.0) = Field(
        2.0, description="A cluster of fewer points than weak_margin x MinPts is weakly supported (2: fewer than twice "
        "the views a fruit needs).")
    min_spread: Real(0.0, math.pi) = Field(
        0.35, description="A cluster whose view directions (its centre to the cameras) all lie within this angle of "
        "one another was seen from one side only, and is weak, rad.")
    weak_real: Fraction = Field(1.0, description="Probability that a weak cluster is a real ripe fruit of its plant.")
    hidden: Real(0.0, 100.0) = Field(
        0.02, description="Expected ripe fruit of a plant that no cluster stands for, however well it was seen.")
    hidden_per_lone: Real(0.0, 100.0) = Field(
        0.3, description="Expected hidden ripe fruit added by each lone detection of the plant: one in no cluster and "
        "farther than 2 eps from every counted fruit, a fruit seen once.")
    hidden_unseen: Real(0.0, 1000.0) = Field(
        0.0, description="Expected hidden ripe fruit of a plant whose canopy box no depth frame has seen, scaled by the "
        "unseen fraction (from an adaptive mission's voxel maps; a batch count has none). Fitted on the mission's first "
        "decisions (benchmarks/intervals.py --first-pass; docs/stages/counting.md).")


class CountingConfig(Strict):
    """Yield counting (OPTICS on the multi-view fruit points of each row) and the harvest plan."""

    points: Count(2, 100_000) = Field(500, description="Size of the fixed point set OPTICS clusters per row and class.")
    eps: Real(0.001, 1.0) = Field(0.04, description="OPTICS neighbourhood (eps and max_eps), m: about one pepper.")
    augment_noise_std: Real(0.0, 1.0) = Field(0.01, description="Sigma of the gaussian copies that fill a row up to `points`, m.")
    use_layout: bool = Field(True, description="Assign and filter points by the plant volumes; false: nearest table and LocalOutlierFactor.")
    expected_per_plant: Count(1, 1000) = Field(
        10, description="Fruit a plant may bear (the paper's 10); informational, the counting itself does not use it."
    )
    volume_margin: Real(0.0, 1.0) = Field(0.02, description="Growth of each plant's bounding box before points are tested against it, m.")
    min_views: Count(2, 1000) = Field(2, description="Detections a pepper needs; MinPts = min_views * ceil(points / n_init).")
    lone_credit: Fraction = Field(
        0.0, description="Ripe fruit each lone detection (a fruit seen once: one detection in no cluster, farther than "
        "2 eps from every counted fruit) adds to its plant's estimate, rounded per plant. 0: the paper's count, clusters "
        "only. A sparse scan sees many real fruit once, a dense one sees a real fruit again: fit it per scan "
        "(benchmarks/intervals.py).")
    unripe_lone_credit: Fraction = Field(
        0.0, description="The same for green fruit: green fruit each lone green detection adds to its plant's green "
        "estimate, rounded per plant. 0: clusters only. Fit it per scan and detector, like lone_credit "
        "(benchmarks/green_credit.py).")
    cluster_method: Literal["dbscan", "xi"] = Field("dbscan", description="OPTICS cluster extraction (scikit-learn).")
    xi: Real(0.0, 1.0, low_open=True, high_open=True) = Field(0.05, description="Steepness for cluster_method 'xi'.")
    split_distance: Real(0.01, 1.0) | None = Field(
        0.07, description="A cluster whose detections fall into two groups (cut along their principal axis), each of "
        "min_views detections, with centres this far apart or more is two fruit whose points chained, m: about a "
        "pepper's width (one fruit's points never spread so far, two fruit's centres are never closer). null: the "
        "paper's rule, one cluster one fruit.")
    lof_neighbors: Count(2, 1000) = Field(
        4, description="LocalOutlierFactor n_neighbors when use_layout is false; keep it below the fewest views of a fruit."
    )
    harvest_min_ripe: Count(1, 1000) = Field(1, description="Ripe fruit a plant must be expected to bear to be brought to the workstation.")
    interval: IntervalConfig = Field(IntervalConfig(), description="The interval of each plant's, row's and the total ripe count.")
