"""Which row, and which plant, a 3D detection belongs to.

With the layout known (the greenhouse is structured, docs/design.md) a point belongs to
the plant whose bounding volume, grown by a small margin for depth noise and for
points on the fruit's skin, holds it; the row is that plant's row, and a point in no
volume (pot rim, table, floor, a neighbour's leaf) is a false positive. Without the
layout a point goes to the nearest table and the false positives are the local
outliers that LocalOutlierFactor finds among the row's points (the paper's fallback,
Breunig et al. 2000).
"""

from __future__ import annotations

import numpy as np

from renderloop.scene.model import Row, Scene

NO_PLANT = -1


def _boxes(scene: Scene, margin: float) -> tuple[np.ndarray, np.ndarray]:
    low = np.array([plant.bounds.min for plant in scene.plants], dtype=float) - margin
    high = np.array([plant.bounds.max for plant in scene.plants], dtype=float) + margin
    return low, high


def _box_distance(points: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """(N, P) euclidean distance of every point to every box; 0 inside."""
    outside = np.maximum(low[None] - points[:, None], 0.0) + np.maximum(points[:, None] - high[None], 0.0)
    return np.linalg.norm(outside, axis=2)


def _box_centre_distance(points: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points[:, None] - ((low + high) / 2)[None], axis=2)


def plants_by_volume(scene: Scene, points: np.ndarray, margin: float) -> np.ndarray:
    """Plant id of each point (N, 3) whose grown volume holds it, NO_PLANT for none.

    Volumes only overlap when the margin exceeds half the gap between plants; a point
    in two then goes to the plant whose volume centre is nearer.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if not len(points) or not scene.plants:
        return np.full(len(points), NO_PLANT, dtype=int)
    low, high = _boxes(scene, margin)
    inside = _box_distance(points, low, high) == 0.0
    nearest = np.argmin(np.where(inside, _box_centre_distance(points, low, high), np.inf), axis=1)
    ids = np.array([plant.id for plant in scene.plants], dtype=int)
    return np.where(inside.any(axis=1), ids[nearest], NO_PLANT)


def rows_by_table(scene: Scene, points: np.ndarray) -> np.ndarray:
    """Row id of each point: the table whose centre line (the segment along y through the
    table's centre, as long as the table) is nearest in x-y. Tables in line along x at
    different y (the paper's two blocks) are told apart by the segment ends."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if not len(points):
        return np.zeros(0, dtype=int)
    centers = np.array([row.table.center[:2] for row in scene.rows], dtype=float)
    half = np.array([row.table.size[1] / 2 for row in scene.rows], dtype=float)
    dx = points[:, None, 0] - centers[None, :, 0]
    dy = np.maximum(np.abs(points[:, None, 1] - centers[None, :, 1]) - half[None], 0.0)
    ids = np.array([row.id for row in scene.rows], dtype=int)
    return ids[np.argmin(np.hypot(dx, dy), axis=1)]


def lof_inliers(points: np.ndarray, n_neighbors: int) -> np.ndarray:
    """True for the points LocalOutlierFactor keeps; rows of fewer than 3 points are kept whole,
    since a local density needs neighbours to compare with.

    `n_neighbors` must stay below the fewest detections of a fruit that should count: with
    more neighbours than a fruit has detections, LOF compares the fruit's points with points
    of other fruit and scores a whole fruit seen a few times an outlier (scikit-learn's
    default of 20 does). LOF also drops some tail points of real fruit, which does not
    change the count.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) < 3:
        return np.ones(len(points), dtype=bool)
    from sklearn.neighbors import LocalOutlierFactor  # here: see cluster.py

    lof = LocalOutlierFactor(n_neighbors=min(n_neighbors, len(points) - 1))
    return lof.fit_predict(points) == 1


def plant_of_center(scene: Scene, row: Row, center: np.ndarray, use_layout: bool, margin: float) -> int:
    """The plant a counted pepper is credited to.

    With the layout: the plant of the row whose grown volume holds the centre, else the
    row's plant whose volume is nearest. Without it: the row's plant whose stem axis
    (pot position, vertical) is nearest in x-y, the only per-plant fact a greenhouse
    without a known layout still has (where the pots stand).
    """
    plants = [scene.plant(plant_id) for plant_id in row.plants]
    center = np.asarray(center, dtype=float).reshape(1, 3)
    if use_layout:
        low = np.array([plant.bounds.min for plant in plants], dtype=float) - margin
        high = np.array([plant.bounds.max for plant in plants], dtype=float) + margin
        distance = _box_distance(center, low, high)[0]
        tie_break = _box_centre_distance(center, low, high)[0]
        return plants[int(np.lexsort((tie_break, distance))[0])].id
    stems = np.array([plant.position[:2] for plant in plants], dtype=float)
    return plants[int(np.argmin(np.linalg.norm(stems - center[0, :2], axis=1)))].id


def rows_of_points(scene: Scene, points: np.ndarray, use_layout: bool, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """The row each point (N, 3) is counted in, and the row of the table nearest it. With the layout a point's row is
    that of the plant whose grown volume holds it, NO_PLANT for a point in none (a false positive, shown beside the
    nearest table's row); without it, the nearest table's."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    nearest = rows_by_table(scene, points)
    if not use_layout:
        return nearest, nearest
    row_of_plant = {plant.id: plant.row for plant in scene.plants}
    plants = plants_by_volume(scene, points, margin)
    return np.array([row_of_plant.get(int(p), NO_PLANT) for p in plants], dtype=int), nearest
