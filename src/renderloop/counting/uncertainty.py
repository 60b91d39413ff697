"""How sure the ripe count of each plant is: an interval per plant, row and in total, from the detections so far.

The count (`renderloop.counting.cluster`) says how many clusters each plant has; this says how far
the true count may be from it, from four kinds of evidence:

1. **Weak clusters.** A counted cluster is weak when it barely made MinPts (fewer points than
   `weak_margin` x MinPts, `ClusterEvidence.margin`) or when it was seen from one side only (its
   view directions, from its centre to the cameras, all within `min_spread` of one another). A weak
   cluster may be a false detection that clustered.
2. **Lone detections.** A detection in no cluster and farther than 2 eps (a fruit's width) from
   every counted fruit: a fruit seen once, which the clustering cannot take for a fruit. Their points
   (`.lone_points`) are where a mission should look again, as are the weak clusters'. The estimate
   credits each with `counting.lone_credit` of a fruit, rounded per plant (`credited`; 0: the
   paper's count of clusters). A dense scan sees a real fruit again, so its detections seen once are
   more often false and want a small credit; a sparse one sees many real fruit only once.
3. **Redraws.** Each row is counted again with other draws of its random fixed set (the subsample,
   or the augmentation's copies; `count_rows(..., draw=r)`, each draw its own stream of the run's
   seed). Draw 0 is the count itself, so nothing about the estimate changes; clusters that split or
   merge from draw to draw show as a plant's count varying across draws.
4. **Unseen canopy.** An optional fraction per plant of its canopy box that no depth frame has seen
   (the mission's voxel map); fruit there cannot have been counted.

The model, with its free parameters in `counting.interval` (`IntervalConfig`): in each draw a
plant's count is

    sum over its clusters of Bernoulli(p) + Poisson(hidden + hidden_per_lone * lone + hidden_unseen * unseen)

with p = 1 for a strong cluster and `weak_real` for a weak one, `lone` the plant's lone detections
and `unseen` its unseen fraction (0 when unknown). The plant's distribution is the equal mixture of
its draws' distributions, each computed exactly (the Poisson-binomial convolved with the Poisson pmf,
cut where less than 1e-12 of the Poisson is left), so it is deterministic. The interval at `level`
is its central one: the narrowest [low, high] that leaves out at most (1 - level) / 2 of the
probability on each side. A row's distribution is its plants' convolved (plants independent), the
total the rows' convolved: the bounds are the quantiles of the sum, not sums of bounds. counts.json
keeps each row's (`stored_distribution`), so rows counted by different missions add up the same way
(`renderloop.counting.merge`).

The interval is of the true count and need not hold the estimate: a plant likely to hide fruit has
its interval above the estimate. Nor is a sum's interval bounded by its plants' widths: many plants
each unlikely to hide a fruit are, together, likely to hide one.

The parameters were fitted on demo runs by `benchmarks/intervals.py`, and the greenhouse preset's on its own
runs (docs/stages/counting.md).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from renderloop.config import CountingConfig, IntervalConfig
from renderloop.counting.assign import plant_of_center
from renderloop.counting.cluster import RowCount, RowMemo, class_detections, count_rows
from renderloop.errors import UserError
from renderloop.rundir.models import DetectionFrame
from renderloop.scene.model import Scene

LABEL = "ripe"  # the interval is of the ripe count: ripe fruit are what the harvest plan is for
POISSON_TAIL = 1e-12  # Poisson probability left out past the last count kept
LONE_AWAY = 2.0  # a detection in no cluster is a fruit seen once when it is this many eps (a fruit's width) from every counted one
QUANTILE_SLACK = 1e-9  # cumulative probabilities this close to a tail's share count as equal to it (rounding, not evidence)
# counts.json keeps a row's distribution to where less than this is left beyond, each probability to this many
# significant digits: the cumulative probabilities of a sum of stored distributions are then within 1e-10 of the exact
# sum's, far inside QUANTILE_SLACK, so a merge of rows (`renderloop.counting.merge`) finds the interval that counting
# them together does
DISTRIBUTION_TAIL = 1e-12
DISTRIBUTION_DIGITS = 10


@dataclass(frozen=True)
class ClusterEvidence:
    """What one counted cluster rests on."""

    center: np.ndarray  # (3,) world frame, m
    support: int  # detections (views, not augmented copies) in it
    margin: float  # its points over MinPts: 1 is just enough to be a cluster at all
    spread: float | None  # rad, widest angle between two directions it was seen from; None: no camera known

    def weak(self, interval: IntervalConfig) -> bool:
        one_side = self.spread is not None and self.spread < interval.min_spread
        return self.margin < interval.weak_margin or one_side


@dataclass(frozen=True)
class PlantEvidence:
    """Everything the interval of one plant is computed from: its clusters in each draw, and its unseen canopy."""

    id: int
    row: int
    draws: tuple[tuple[ClusterEvidence, ...], ...]  # the plant's clusters in each draw; draw 0 is the count
    lone: tuple[int, ...]  # per draw, the plant's detections in no cluster and away from every counted fruit
    unseen: float | None  # share of its canopy box no depth frame has seen; None: unknown
    lone_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (L, 3) draw 0's lone detections, m

    @property
    def estimate(self) -> int:
        """The clusters of the count (draw 0), before any credit for its lone detections."""
        return len(self.draws[0])


def credit_of(lone: int, lone_credit: float) -> int:
    """What a plant's `lone` detections add to its estimate: `lone_credit` of a fruit each, rounded half up."""
    return math.floor(lone_credit * lone + 0.5)


def credited(plant: PlantEvidence, lone_credit: float) -> int:
    """The plant's estimate: its clusters plus the credit of its lone detections (draw 0, `credit_of`)."""
    return plant.estimate + credit_of(plant.lone[0], lone_credit)


@dataclass(frozen=True)
class CountUncertainty:
    """A ripe count and the distribution of the true count it stands for."""

    estimate: int  # the count (draw 0; for a plant, with its lone detections' credit)
    low: int  # the interval's lower bound
    high: int  # the interval's upper bound
    level: float  # probability that the true count is in [low, high]
    pmf: np.ndarray  # P(true count = k), k = 0, 1, ...

    @property
    def settled(self) -> bool:
        """Nothing more to learn at this level: the interval is the estimate alone."""
        return self.low == self.high == self.estimate

    @property
    def width(self) -> int:
        return self.high - self.low


@dataclass(frozen=True)
class PlantUncertainty(CountUncertainty):
    id: int
    row: int
    weak_centers: np.ndarray  # (K, 3) world positions of the count's weak clusters, m
    lone_points: np.ndarray  # (L, 3) world positions of the count's lone detections (fruit seen once), m
    redraw_counts: np.ndarray  # (R,) the plant's count in each draw; [0] is the estimate
    unseen: float | None  # share of the canopy box no depth frame has seen; None: unknown
    clusters: tuple[ClusterEvidence, ...]  # the count's clusters (draw 0)


@dataclass(frozen=True)
class Uncertainty:
    plants: dict[int, PlantUncertainty]
    rows: dict[int, CountUncertainty]
    total: CountUncertainty


# Evidence ----------------------------------------------------------------------------------------------------------

def view_spread(center: np.ndarray, cameras: np.ndarray) -> float:
    """Widest angle (rad) between two directions from `center` to the camera positions (N, 3); 0 for one direction."""
    directions = np.asarray(cameras, dtype=float).reshape(-1, 3) - np.asarray(center, dtype=float).reshape(1, 3)
    lengths = np.linalg.norm(directions, axis=1)
    directions = directions[lengths > 0] / lengths[lengths > 0, None]
    if len(directions) < 2:
        return 0.0
    return float(np.arccos(np.clip((directions @ directions.T).min(), -1.0, 1.0)))


def _draw_evidence(scene: Scene, rows: list[RowCount], seen_in: np.ndarray, cameras: Mapping[int, np.ndarray],
                   counting: CountingConfig) -> tuple[dict[int, list[ClusterEvidence]], dict[int, list[np.ndarray]]]:
    """Per plant, the evidence of the clusters credited to it in one draw of every row, and its lone detections."""
    plants: dict[int, list[ClusterEvidence]] = {}
    for row in rows:
        clusters = row.clusters
        for k, (plant, center, support) in enumerate(zip(row.plants, clusters.centers, clusters.support())):
            frames = np.unique(seen_in[row.indices[clusters.members(k)]])
            known = [cameras[int(frame)] for frame in frames if int(frame) in cameras]
            spread = view_spread(center, np.array(known)) if known else None
            margin = np.count_nonzero(clusters.labels == k) / clusters.min_samples
            plants.setdefault(int(plant), []).append(ClusterEvidence(np.asarray(center, dtype=float), int(support),
                                                                     float(margin), spread))
    return plants, lone_detections(scene, rows, counting)


def lone_detections(scene: Scene, rows: Iterable[RowCount], counting: CountingConfig) -> dict[int, list[np.ndarray]]:
    """Per plant, the points of the rows' detections in no cluster and farther than LONE_AWAY eps from every counted
    fruit of their row and class: fruit seen once (either class: the rows say which)."""
    lone: dict[int, list[np.ndarray]] = {}
    layout = {row.id: row for row in scene.rows}
    for row in rows:
        clusters = row.clusters
        for point in clusters.points[clusters.original & (clusters.labels < 0)]:
            if len(clusters.centers) and np.linalg.norm(clusters.centers - point, axis=1).min() <= LONE_AWAY * counting.eps:
                continue  # a stray view of a counted fruit, not a fruit seen once
            plant = plant_of_center(scene, layout[row.row], point, counting.use_layout, counting.volume_margin)
            lone.setdefault(plant, []).append(point)
    return lone


def _checked_unseen(scene: Scene, unseen: Mapping[int, float | None] | None) -> dict[int, float | None]:
    known = {plant.id for plant in scene.plants}
    fractions: dict[int, float | None] = {plant_id: None for plant_id in known}
    for plant_id, fraction in (unseen or {}).items():
        if int(plant_id) not in known:
            raise UserError(f"unseen: plant {plant_id} is not a plant of the scene")
        if fraction is not None and not 0.0 <= float(fraction) <= 1.0:
            raise UserError(f"unseen: plant {plant_id}'s unseen fraction {fraction} is not within [0, 1]")
        fractions[int(plant_id)] = None if fraction is None else float(fraction)
    return fractions


def evidence(scene: Scene, frames: Iterable[DetectionFrame], camera_positions: Mapping[int, np.ndarray],
             counting: CountingConfig, seed: int, unseen: Mapping[int, float | None] | None = None,
             estimate: Sequence[RowCount] | None = None, memo: RowMemo | None = None) -> dict[int, PlantEvidence]:
    """Per plant, its clusters and lone detections in each of `counting.interval.redraws` draws, and its unseen fraction.

    `camera_positions` maps a frame index to the camera's position in the world (m); a cluster
    none of whose frames is in it has no spread (it is judged by its support alone).
    `estimate`: the ripe rows `count_rows` already made of these frames' points (draw 0), to
    spare counting them again. The cost is the redraws: redraws - 1 counts of the ripe rows,
    of only the rows whose detections changed with a `memo` (`count_rows`).
    """
    points, seen_in = class_detections(frames, counting.eps)[LABEL]
    fractions = _checked_unseen(scene, unseen)
    cameras = {int(index): np.asarray(position, dtype=float).reshape(3) for index, position in camera_positions.items()}
    draws = [list(estimate) if estimate is not None else count_rows(scene, points, LABEL, counting, seed, memo=memo)]
    if len(draws[0]) != len(scene.rows) or any(len(row.indices) and row.indices.max() >= len(points) for row in draws[0]):
        raise ValueError("estimate: not the ripe rows counted from these frames")
    draws += [count_rows(scene, points, LABEL, counting, seed, draw, memo) for draw in range(1, counting.interval.redraws)]
    per_draw = [_draw_evidence(scene, rows, seen_in, cameras, counting) for rows in draws]
    return {plant.id: PlantEvidence(plant.id, plant.row, tuple(tuple(found.get(plant.id, ())) for found, _ in per_draw),
                                    tuple(len(lone.get(plant.id, ())) for _, lone in per_draw), fractions[plant.id],
                                    np.array(per_draw[0][1].get(plant.id, []), dtype=float).reshape(-1, 3))
            for plant in scene.plants}


# The model ---------------------------------------------------------------------------------------------------------

def poisson_pmf(mean: float) -> np.ndarray:
    """P(k), k = 0 .. n, of a Poisson of this mean, cut where less than POISSON_TAIL is left beyond, renormalised."""
    if mean <= 0.0:
        return np.ones(1)
    n = math.ceil(mean + 12.0 * math.sqrt(mean) + 12.0)  # far past the 1e-12 tail for any mean
    k = np.arange(n + 1)
    pmf = np.exp(k * math.log(mean) - mean - np.array([math.lgamma(i + 1.0) for i in k]))
    last = int(np.searchsorted(np.cumsum(pmf), 1.0 - POISSON_TAIL)) + 1
    pmf = pmf[:max(last, 1)]
    return pmf / pmf.sum()


def poisson_binomial_pmf(probabilities: Iterable[float]) -> np.ndarray:
    """P(k successes) of independent Bernoulli trials, by convolution."""
    pmf = np.ones(1)
    for p in probabilities:
        pmf = np.convolve(pmf, [1.0 - p, p])
    return pmf


def _mixture(pmfs: list[np.ndarray]) -> np.ndarray:
    size = max(len(pmf) for pmf in pmfs)
    return np.mean([np.pad(pmf, (0, size - len(pmf))) for pmf in pmfs], axis=0)


def plant_pmf(plant: PlantEvidence, interval: IntervalConfig) -> np.ndarray:
    """The distribution of the plant's true ripe count under the model (module docstring), mixed over its draws."""
    unseen = 0.0 if plant.unseen is None else plant.unseen
    pmfs = []
    for clusters, lone in zip(plant.draws, plant.lone):
        weak = [cluster.weak(interval) for cluster in clusters]
        hidden = interval.hidden + interval.hidden_per_lone * lone + interval.hidden_unseen * unseen
        pmfs.append(np.convolve(poisson_binomial_pmf(interval.weak_real if w else 1.0 for w in weak), poisson_pmf(hidden)))
    return _mixture(pmfs)


def central_interval(pmf: np.ndarray, level: float) -> tuple[int, int]:
    """The narrowest [low, high] leaving out at most (1 - level) / 2 of the probability on each side."""
    cdf = np.cumsum(pmf)
    tail = (1.0 - level) / 2.0
    low = np.searchsorted(cdf, tail + QUANTILE_SLACK, side="right")  # counts below low hold at most `tail`
    high = np.searchsorted(cdf, 1.0 - tail - QUANTILE_SLACK, side="left")  # counts above high hold at most `tail`
    return int(min(low, len(pmf) - 1)), int(min(high, len(pmf) - 1))


def _count_uncertainty(estimate: int, pmf: np.ndarray, level: float) -> CountUncertainty:
    low, high = central_interval(pmf, level)
    return CountUncertainty(estimate, low, high, level, pmf)


def convolved(pmfs: Iterable[np.ndarray]) -> np.ndarray:
    """The distribution of the sum of independent counts with these distributions."""
    total = np.ones(1)
    for pmf in pmfs:
        total = np.convolve(total, np.asarray(pmf, dtype=float))
    return total


def stored_distribution(pmf: np.ndarray) -> list[float]:
    """A count's distribution as counts.json keeps it: cut after the last count whose tail beyond holds DISTRIBUTION_TAIL
    or more, and rounded to DISTRIBUTION_DIGITS significant digits, so the same count gives the same bytes."""
    pmf = np.asarray(pmf, dtype=float)
    beyond = np.cumsum(pmf[::-1])[::-1] - pmf  # beyond[k]: the probability of counts above k
    kept = int(np.argmax(beyond < DISTRIBUTION_TAIL)) + 1 if len(pmf) else 0
    return [float(f"{value:.{DISTRIBUTION_DIGITS}g}") for value in pmf[:kept]]


def from_evidence(scene: Scene, plants: Mapping[int, PlantEvidence], interval: IntervalConfig,
                  lone_credit: float = 0.0) -> Uncertainty:
    """The estimates (`credited`) and intervals of every plant, row and the total under the model's parameters
    `interval`: cheap, so a calibration can try many parameters on evidence gathered once."""
    level = interval.level
    found: dict[int, PlantUncertainty] = {}
    for plant in scene.plants:
        basis = plants[plant.id]
        pmf = plant_pmf(basis, interval)
        low, high = central_interval(pmf, level)
        clusters = basis.draws[0]
        weak = np.array([c.center for c in clusters if c.weak(interval)], dtype=float).reshape(-1, 3)
        found[plant.id] = PlantUncertainty(
            credited(basis, lone_credit), low, high, level, pmf, id=plant.id, row=plant.row, weak_centers=weak,
            lone_points=basis.lone_points, redraw_counts=np.array([len(draw) for draw in basis.draws], dtype=int),
            unseen=basis.unseen, clusters=clusters)
    rows = {}
    for row in scene.rows:
        mine = [found[plant_id] for plant_id in row.plants]
        rows[row.id] = _count_uncertainty(sum(p.estimate for p in mine), convolved(p.pmf for p in mine), level)
    total = _count_uncertainty(sum(r.estimate for r in rows.values()), convolved(r.pmf for r in rows.values()), level)
    return Uncertainty(found, rows, total)


def uncertainty(scene: Scene, frames: Iterable[DetectionFrame], camera_positions: Mapping[int, np.ndarray],
                counting: CountingConfig, seed: int, unseen: Mapping[int, float | None] | None = None,
                estimate: Sequence[RowCount] | None = None, memo: RowMemo | None = None) -> Uncertainty:
    """The ripe count's interval per plant (`.plants[id]`), per row (`.rows[id]`) and in total (`.total`), from
    the detections of `frames`; see `evidence` for the arguments and the module docstring for the model."""
    plants = evidence(scene, frames, camera_positions, counting, seed, unseen, estimate, memo)
    return from_evidence(scene, plants, counting.interval, counting.lone_credit)
