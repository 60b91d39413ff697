"""Count the fruit of one row: resample its detection points to a fixed set, cluster it with OPTICS.

The reference work (docs/design.md, paper "Ripe fruit count") turns the multi-view 3D points
of one row into a fixed set of `points` (500): a random subsample when there are more,
gaussian copies of the detections when there are fewer. OPTICS then runs with
eps = 4 cm (a pepper's size) and MinPts = 2 * ceil(500 / n_init): "a pepper is seen at
least twice", scaled by how many copies augmentation made of each detection. Every
cluster is one pepper, unless it holds two (below).

That scaling holds exactly only if every detection owns ceil(500 / n_init) points, so
each detection gets exactly that many and the set holds n_init * ceil(500 / n_init)
points (500 up to 500 + n_init - 1) instead of exactly 500: filled to exactly 500, some
detections get a place fewer, and a fruit seen twice through two of them falls short of
MinPts.

The extraction is scikit-learn's `dbscan` cut of the reachability plot at eps (a cluster
is a set of points chained by core points at most 4 cm apart, the paper's wording), not
`xi`, which splits a subsampled fruit's cloud at small valleys; both use max_eps = eps.
Two fruit whose skin points come within 4 cm of each other chain into one cluster: the
paper's rule. Past the paper, a cluster whose detections fall into two groups whose
centres lie at least `split_distance` apart (a pepper's width: one fruit's points never
spread that far, two fruit's centres are never closer) is split in two, each group seen
at least min_views times, and each part again (`split_chained`). The measurements behind
each choice are in docs/stages/counting.md.

Each class is counted apart, so a fruit the detector calls ripe in a few of its views and
green in the rest would be counted twice, once in each class. One fruit has one ripeness:
before the classes are split, each detection takes the class most of the detections within
eps of its point hold (`voted_labels`).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from renderloop.config import CountingConfig
from renderloop.counting.assign import (
    NO_PLANT,
    lof_inliers,
    plant_of_center,
    rows_of_points,
)
from renderloop.rundir.models import DetectionFrame
from renderloop.scene.model import Scene

CLASSES = ("ripe", "unripe")


@dataclass(frozen=True)
class ClusterParams:
    points: int  # size of the fixed set OPTICS sees
    eps: float  # m, neighbourhood radius (and max_eps)
    noise_std: float  # m, sigma of the augmentation noise
    min_views: int  # detections a pepper needs (the paper's 2)
    method: str  # "dbscan" or "xi"
    xi: float = 0.05
    split_distance: float | None = None  # m between two groups' centres that makes a cluster two fruit; None: never


@dataclass(frozen=True)
class RowClusters:
    """The fixed set a row was clustered on, and what OPTICS made of it."""

    points: np.ndarray  # (M, 3) world points
    original: np.ndarray  # (M,) True for detections, False for augmented copies
    labels: np.ndarray  # (M,) cluster index, -1 = noise
    centers: np.ndarray  # (K, 3) one per cluster, in label order
    n_init: int  # detections of the row before resampling
    min_samples: int  # MinPts used (0 when the row was too small to cluster)
    source: np.ndarray  # (M,) the row detection each point is, or is a copy of

    def support(self) -> np.ndarray:
        """(K,) detections (not augmented copies) in each cluster, in cluster order: the views that make a fruit."""
        return np.array([np.count_nonzero(self.original & (self.labels == k)) for k in range(len(self.centers))], dtype=int)

    def members(self, cluster: int) -> np.ndarray:
        """The row detections (indices into the row's points) that are in one cluster; copies do not count."""
        return self.source[self.original & (self.labels == cluster)]


def rng_for(seed: int, row: int, label: str, draw: int = 0) -> np.random.Generator:
    """One generator per (run seed, row, class), so a row's counts do not depend on the order rows are done in.

    Draw 0 is the count's own stream; draws 1, 2, ... are further streams of the same
    (row, class), for redrawing the random fixed set (`renderloop.counting.uncertainty`)
    without changing the count. SeedSequence pads its entropy with zeros, so the draw is
    appended only when it is not 0: [seed, row, class, 0] would be draw 0's stream anyway.
    """
    entropy = [seed, row, CLASSES.index(label)] + ([draw] if draw else [])
    return np.random.default_rng(np.random.SeedSequence(entropy))


def min_samples_for(n_init: int, points: int, min_views: int) -> int:
    """MinPts = min_views * ceil(points / n_init), kept within [min_views, points].

    With more detections than `points` the ratio is 1: a subsample keeps at most one
    point per detection, so MinPts is just min_views. The cap keeps MinPts within the
    set OPTICS sees.
    """
    return int(min(points, max(min_views, min_views * math.ceil(points / n_init))))


def resample(detections: np.ndarray, points: int, noise_std: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The fixed set: a random subsample of `points` detections, or every detection plus
    gaussian copies so that each owns exactly ceil(points / n) places.

    Equal shares are what MinPts = min_views * ceil(points / n) assumes: a pepper seen k
    times owns k * ceil(points / n) points, so "seen twice" is exactly the threshold.
    Returns the points and, per point, whether it is a detection (not a copy).
    """
    fixed, original, _ = _resample(detections, points, noise_std, rng)
    return fixed, original


def _resample(detections: np.ndarray, points: int, noise_std: float,
              rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`resample`, and also the detection each point is or copies."""
    n = len(detections)
    if n >= points:
        keep = np.sort(rng.choice(n, size=points, replace=False))
        return detections[keep], np.ones(points, dtype=bool), keep
    extra = np.tile(np.arange(n), math.ceil(points / n) - 1)
    copies = detections[extra] + rng.normal(0.0, noise_std, size=(len(extra), 3))
    original = np.concatenate([np.ones(n, dtype=bool), np.zeros(len(extra), dtype=bool)])
    return np.vstack([detections, copies]), original, np.concatenate([np.arange(n), extra])


def _centers(points: np.ndarray, original: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Mean of each cluster's detections (its augmented copies only add noise), or of all its points if it has none."""
    centers = []
    for label in range(labels.max() + 1 if len(labels) else 0):
        members = labels == label
        own = members & original
        centers.append(points[own if own.any() else members].mean(axis=0))
    return np.array(centers, dtype=float).reshape(-1, 3)


def cluster_row(detections: np.ndarray, params: ClusterParams, rng: np.random.Generator) -> RowClusters:
    """Cluster the 3D detections (N, 3) of one row and class; one cluster centre per counted pepper."""
    detections = np.asarray(detections, dtype=float).reshape(-1, 3)
    n_init = len(detections)
    if n_init < params.min_views:  # nobody saw a pepper twice: nothing to count
        empty = np.zeros((0, 3))
        return RowClusters(detections, np.ones(n_init, dtype=bool), -np.ones(n_init, dtype=int), empty, n_init, 0,
                           np.arange(n_init))
    # imported here, not at the top: scikit-learn and numba would cost every command that reads this module a second
    from scipy.spatial.distance import cdist

    from renderloop.counting.optics import optics_labels

    points, original, source = _resample(detections, params.points, params.noise_std, rng)
    min_samples = min_samples_for(n_init, params.points, params.min_views)
    labels = optics_labels(cdist(points, points), min_samples, params.eps, params.method, params.xi).astype(int)
    if params.split_distance is not None:
        labels = split_chained(points, original, source, labels, params.split_distance, params.min_views)
    return RowClusters(points, original, labels, _centers(points, original, labels), n_init, min_samples, source)


def _two_groups(points: np.ndarray, least: int) -> np.ndarray | None:
    """The best cut of (N, 3) points into two groups of at least `least` along their principal axis (least squares,
    exact: every cut of the sorted projections is tried); a mask of the second group, or None if none can be made."""
    n = len(points)
    if n < 2 * least:
        return None
    centred = points - points.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    along = centred @ axis
    order = np.argsort(along, kind="stable")
    ranked = along[order]
    first = np.cumsum(ranked)
    # SSE of ranked[:i] + SSE of ranked[i:] up to a constant: -(sum_left^2 / i) - (sum_right^2 / (n - i))
    cuts = np.arange(least, n - least + 1)
    left, right = first[cuts - 1], first[-1] - first[cuts - 1]
    best = cuts[np.argmin(-(left**2) / cuts - right**2 / (n - cuts))]
    second = np.zeros(n, dtype=bool)
    second[order[best:]] = True
    return second


def split_chained(points: np.ndarray, original: np.ndarray, source: np.ndarray, labels: np.ndarray, distance: float,
                  min_views: int) -> np.ndarray:
    """Labels with every cluster that holds two fruit split: its detections cut in two along their principal axis,
    kept apart when both parts have min_views detections and their centres are `distance` or more apart. Each part is
    tried again. An augmented copy goes with the detection it copies; the part holding the cluster's first detection
    keeps the label, the other gets the next free one, so the labels do not depend on the axis's sign."""
    labels = labels.copy()
    todo = np.unique(labels[labels >= 0]).tolist()
    while todo:
        label = todo.pop(0)
        own = np.flatnonzero(original & (labels == label))
        second = _two_groups(points[own], min_views)
        if second is None:
            continue
        if np.linalg.norm(points[own[second]].mean(axis=0) - points[own[~second]].mean(axis=0)) < distance:
            continue
        if second[np.argmin(source[own])]:
            second = ~second
        new = int(labels.max()) + 1
        labels[(labels == label) & np.isin(source, source[own[second]])] = new
        todo += [label, new]
    return labels


@dataclass(frozen=True)
class RowCount:
    """One row and class counted: the clustering, the plant each counted pepper is credited to,
    and the detections thrown out as false positives near this row (for the plot)."""

    row: int
    label: str
    clusters: RowClusters
    plants: np.ndarray  # (K,) plant id of each cluster centre
    removed: np.ndarray  # (R, 3)
    indices: np.ndarray  # (n_init,) where each of the row's clustered detections is in the class's points


def voted_labels(points: np.ndarray, labels: np.ndarray, radius: float) -> np.ndarray:
    """Each point's class (an index into CLASSES) by the points within `radius` of it, its own among them: the class
    most of them hold, its own on a tie. The points of one fruit lie within a centimetre or two of its centre and
    those of two fruit a fruit's width apart, so at OPTICS' eps a point's neighbours are its fruit's views."""
    from sklearn.neighbors import KDTree

    if len(points) == 0:
        return labels
    votes = np.stack([KDTree(points[labels == k]).query_radius(points, radius, count_only=True)
                      if np.any(labels == k) else np.zeros(len(points), dtype=int) for k in range(len(CLASSES))], axis=1)
    best = votes.max(axis=1)
    return np.where(votes[np.arange(len(points)), labels] == best, labels, votes.argmax(axis=1))


def class_detections(frames: Iterable[DetectionFrame], radius: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """World points (N, 3) of each class in the order the frames come, and the frame index (N,) each was seen in, each
    detection's class voted by those within `radius` of its point (`voted_labels`); detections without depth have no
    place to count."""
    placed = [(detection.position, CLASSES.index(detection.label), frame.index)
              for frame in frames for detection in frame.detections if detection.position is not None]
    points = np.array([position for position, _, _ in placed], dtype=float).reshape(-1, 3)
    seen_in = np.array([index for _, _, index in placed], dtype=int)
    labels = voted_labels(points, np.array([label for _, label, _ in placed], dtype=int), radius)
    return {label: (points[labels == k], seen_in[labels == k]) for k, label in enumerate(CLASSES)}


def class_points(frames: Iterable[DetectionFrame], radius: float) -> dict[str, np.ndarray]:
    """World points of each class, in frame order, each detection's class voted by those within `radius` of it;
    detections without depth have no place to count."""
    return {label: points for label, (points, _) in class_detections(frames, radius).items()}


def params_from(counting: CountingConfig) -> ClusterParams:
    return ClusterParams(points=counting.points, eps=counting.eps, noise_std=counting.augment_noise_std,
                         min_views=counting.min_views, method=counting.cluster_method, xi=counting.xi,
                         split_distance=counting.split_distance)


# (row id, class, draw) -> (seed, counting config, digest of the row's detections, its clustering, its plants)
RowMemo = dict[tuple[int, str, int], tuple[int, CountingConfig, bytes, RowClusters, np.ndarray]]


def count_rows(scene: Scene, detections: np.ndarray, label: str, counting: CountingConfig, seed: int,
               draw: int = 0, memo: RowMemo | None = None) -> list[RowCount]:
    """Split one class's world points (N, 3) into rows, drop the false positives, count every row.

    With `counting.use_layout` the plant volumes both assign and filter; without it the
    nearest table assigns and LocalOutlierFactor filters. Removed points are kept per
    nearest table so the row plots can show them. The paper filters after resampling;
    here the false positives go first, so n_init and the 500 points are all the row's
    own and MinPts is not inflated by detections that are thrown away anyway.

    `draw` 0 is the count; another draw redraws the random fixed set of every row from
    its own stream (`rng_for`), everything else the same. `memo` (one per scene) keeps
    each row's last clustering and reuses it while the row's detections, the seed and the
    settings are the same: a caller that counts again and again as frames come (the
    online counter) then pays only for the rows whose detections changed.
    """
    detections = np.asarray(detections, dtype=float).reshape(-1, 3)
    row_ids, nearest_row = rows_of_points(scene, detections, counting.use_layout, counting.volume_margin)
    params = params_from(counting)
    counts = []
    for row in scene.rows:
        indices = np.flatnonzero(row_ids == row.id)
        mine = detections[indices]
        removed = detections[(row_ids == NO_PLANT) & (nearest_row == row.id)]
        if not counting.use_layout:
            keep = lof_inliers(mine, counting.lof_neighbors)
            mine, removed, indices = mine[keep], mine[~keep], indices[keep]
        key, digest = (row.id, label, draw), hashlib.sha1(mine.tobytes()).digest()
        last = memo.get(key) if memo is not None else None
        if last is not None and last[:3] == (seed, counting, digest):
            clusters, plants = last[3:]
        else:
            clusters = cluster_row(mine, params, rng_for(seed, row.id, label, draw))
            plants = np.array([plant_of_center(scene, row, center, counting.use_layout, counting.volume_margin)
                               for center in clusters.centers], dtype=int)
            if memo is not None:
                memo[key] = (seed, counting, digest, clusters, plants)
        counts.append(RowCount(row.id, label, clusters, plants, removed, indices))
    return counts
