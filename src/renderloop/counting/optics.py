"""OPTICS on a precomputed distance matrix: the reachability graph compiled with numba, the clusters cut by scikit-learn.

scikit-learn's OPTICS walks the points one at a time in Python, each step a radius query
through its estimator API with its input checks, about a millisecond a point: most of a
row's count and of every redraw of the count's interval. `optics_graph` is scikit-learn's
`compute_optics_graph` for `metric="precomputed"`, step for step, so what comes out is the
same to the bit (tests/test_counting.py compares the two on random rows, ties included):

- the core distance of a point is the `min_samples`-th smallest distance in its row (itself
  included), inf beyond `max_eps`;
- the next point is the unprocessed one of least reachability, the lowest index on ties;
- a processed core point offers each unprocessed point within `max_eps` (`<=`, as
  scikit-learn's radius query) the reachability max(distance, its core distance);
- every reachability is rounded to 15 decimals, as scikit-learn rounds it against float noise.

The clusters are then scikit-learn's own extraction (`cluster_optics_dbscan`, `cluster_optics_xi`)
on that graph, with the arguments `OPTICS.fit` passes.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_ROUND = 10.0**15  # scikit-learn rounds to np.finfo(np.float64).precision decimals: x * 1e15, rint, / 1e15


@njit(cache=True)
def _round(x):
    return np.rint(x * _ROUND) / _ROUND


@njit(cache=True)
def _graph(distances, min_samples, max_eps):
    n = distances.shape[0]
    core = np.empty(n)
    for i in range(n):
        value = np.partition(distances[i].copy(), min_samples - 1)[min_samples - 1]
        core[i] = _round(value) if value <= max_eps else np.inf
    reachability = np.full(n, np.inf)
    predecessor = np.full(n, -1, dtype=np.int64)
    processed = np.zeros(n, dtype=np.bool_)
    ordering = np.empty(n, dtype=np.int64)
    for k in range(n):
        point, best = -1, np.inf
        for i in range(n):
            if not processed[i] and (point < 0 or reachability[i] < best):
                point, best = i, reachability[i]
        processed[point] = True
        ordering[k] = point
        if core[point] == np.inf:
            continue
        for j in range(n):
            if not processed[j] and distances[point, j] <= max_eps:
                offered = _round(max(distances[point, j], core[point]))
                if offered < reachability[j]:
                    reachability[j] = offered
                    predecessor[j] = point
    return ordering, core, reachability, predecessor


def optics_graph(distances: np.ndarray, min_samples: int, max_eps: float) -> tuple[np.ndarray, ...]:
    """(ordering, core distances, reachability, predecessor) of the points whose pairwise distances are the
    symmetric (n, n) `distances`, as scikit-learn's `compute_optics_graph` gives them."""
    distances = np.ascontiguousarray(distances, dtype=np.float64)
    if not 2 <= min_samples <= len(distances):
        raise ValueError(f"min_samples {min_samples} must be within [2, {len(distances)}], the number of points")
    return _graph(distances, int(min_samples), float(max_eps))


def optics_labels(distances: np.ndarray, min_samples: int, max_eps: float, method: str, xi: float = 0.05) -> np.ndarray:
    """Cluster labels (-1: noise) as `OPTICS(min_samples=min_samples, max_eps=max_eps, cluster_method=method, xi=xi,
    metric="precomputed").fit(distances).labels_` gives them (the dbscan cut at max_eps)."""
    import sklearn
    from sklearn.cluster import cluster_optics_dbscan, cluster_optics_xi

    ordering, core, reachability, predecessor = optics_graph(distances, min_samples, max_eps)
    with sklearn.config_context(skip_parameter_validation=True):
        if method == "xi":
            return cluster_optics_xi(reachability=reachability, predecessor=predecessor, ordering=ordering,
                                     min_samples=min_samples, min_cluster_size=None, xi=xi,
                                     predecessor_correction=True)[0]
        if method == "dbscan":
            return cluster_optics_dbscan(reachability=reachability, core_distances=core, ordering=ordering,
                                         eps=max_eps)
    raise ValueError(f"unknown OPTICS cluster method {method!r} (choose from: dbscan, xi)")
