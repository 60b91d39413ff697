"""The harvest plan: which plants to bring to the manipulator workstation, and in what order.

In the reference work's greenhouse (paper, "Simulation results") mobile robots carry
plant containers to a stationary manipulator workstation, and the mission planner
acts on the per-plant counts. Here the plan is one round trip from the workstation
through every plant expected to bear at least `min_ripe` ripe fruit: a travelling
salesman tour built greedily (nearest neighbour) and improved by 2-opt until no
segment reversal shortens it. The 2-opt move search is vectorised over the segment's far
end, so a compartment of 1000 plants is planned in well under a second; below about 40
plants the tour is usually optimal or within a few per cent.

Distances are straight lines in x-y between the workstation centre and the plant
positions (pot centres): the tables and the workstation are not routed around, so a
leg is a lower bound on what a ground robot drives.
"""

from __future__ import annotations

import numpy as np

from renderloop.scene.model import Scene

IMPROVEMENT = 1e-9  # m; a 2-opt move must shorten the tour by more than this (no cycling on ties)


def tour_length(start: np.ndarray, stops: np.ndarray, order: list[int]) -> float:
    path = np.vstack([start, stops[order], start]) if order else np.vstack([start, start])
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def nearest_neighbour(start: np.ndarray, stops: np.ndarray) -> list[int]:
    """Greedy tour: always go to the closest unvisited stop (lowest index on ties)."""
    order: list[int] = []
    left = list(range(len(stops)))
    here = start
    while left:
        distances = np.linalg.norm(stops[left] - here, axis=1)
        nearest = left.pop(int(np.argmin(distances)))
        order.append(nearest)
        here = stops[nearest]
    return order


def _distances(x: float | np.ndarray, y: float | np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Straight-line distances from (x, y) to each (xs, ys).

    Elementwise products, sum and square root, each rounded once as IEEE prescribes, so a
    distance is the same bits on every machine (a BLAS dot product may fuse them).
    """
    dx, dy = xs - x, ys - y
    return np.sqrt(dx * dx + dy * dy)


def two_opt(start: np.ndarray, stops: np.ndarray, order: list[int]) -> list[int]:
    """Reverse tour segments while that shortens the closed tour (workstation fixed at both ends).

    First improvement, in a fixed order: with the tour as path[0] = workstation, path[1..n] the
    stops, path[n + 1] = workstation, positions i = 1 .. n - 1 are taken in turn, and for each
    the far ends j = i + 1 .. n; the first (i, j) whose reversal of path[i..j] shortens the
    tour by more than IMPROVEMENT is applied, and the scan goes on at (i, j + 1) on the new
    tour. Sweeps repeat until one applies no move. The gains of all j for one i are computed
    at once as arrays; the moves, and so the tour, are those of the same scan pair by pair.
    """
    order = list(order)
    path = np.vstack([start, stops[order], start]) if order else np.vstack([start, start])
    xs, ys = path[:, 0].copy(), path[:, 1].copy()
    slots = np.arange(len(order))  # slots[k]: the index into `order` of the stop at path[k + 1]
    edge = _distances(xs[1:], ys[1:], xs[:-1], ys[:-1])  # edge[k]: |path[k] - path[k + 1]|
    last = len(path) - 2  # the highest far end j: path[j + 1] is the workstation
    improved = True
    while improved:
        improved = False
        for i in range(1, last):
            first = i + 1
            while first <= last:
                # a = path[i - 1], b = path[i], c = path[j], d = path[j + 1] for every j >= first
                before = edge[i - 1] + edge[first : last + 1]
                to_c = _distances(xs[i - 1], ys[i - 1], xs[first : last + 1], ys[first : last + 1])
                to_d = _distances(xs[i], ys[i], xs[first + 1 :], ys[first + 1 :])
                shorter = to_c + to_d < before - IMPROVEMENT
                k = int(np.argmax(shorter))  # the first improving j, if any
                if not shorter[k]:
                    break
                j = first + k
                xs[i : j + 1] = xs[i : j + 1][::-1].copy()
                ys[i : j + 1] = ys[i : j + 1][::-1].copy()
                slots[i - 1 : j] = slots[i - 1 : j][::-1].copy()
                edge[i:j] = edge[i:j][::-1].copy()
                edge[i - 1], edge[j] = to_c[k], to_d[k]
                improved = True
                first = j + 1
    return [order[slot] for slot in slots]


def two_opt_pair_by_pair(start: np.ndarray, stops: np.ndarray, order: list[int]) -> list[int]:
    """`two_opt`'s scan written out plainly, one (i, j) at a time with numpy's norm of each leg: the reference whose
    moves, and so tour, `two_opt` must equal (tests/test_harvest_speedup.py) and that benchmarks/harvest.py times it
    against. Quadratic Python per sweep: never used in a plan."""
    order = list(order)
    improved = True
    while improved:
        improved = False
        path = np.vstack([start, stops[order], start])
        for i in range(1, len(path) - 2):
            for j in range(i + 1, len(path) - 1):
                a, b, c, d = path[i - 1], path[i], path[j], path[j + 1]
                before = np.linalg.norm(a - b) + np.linalg.norm(c - d)
                after = np.linalg.norm(a - c) + np.linalg.norm(b - d)
                if after < before - IMPROVEMENT:
                    order[i - 1 : j] = order[i - 1 : j][::-1]
                    path = np.vstack([start, stops[order], start])
                    improved = True
    return order


def plan_harvest(scene: Scene, ripe_estimates: dict[int, int], min_ripe: int) -> dict:
    """`harvest.json`: the plants whose ripe estimate is at least `min_ripe`, in visiting order.

    Each stop has the plant `id`, its `row`, `expected_ripe` (the counted ripe fruit),
    its `position` and `leg_distance` (m, from the previous stop or the workstation);
    `return_distance` closes the tour, and `total_distance` is the sum of all legs and
    the return.
    """
    start = np.array(scene.workstation.center[:2], dtype=float)
    chosen = [plant for plant in scene.plants if ripe_estimates.get(plant.id, 0) >= min_ripe]
    stops = np.array([plant.position[:2] for plant in chosen], dtype=float).reshape(-1, 2)
    order = two_opt(start, stops, nearest_neighbour(start, stops))
    plan, here, total = [], start, 0.0
    for index in order:
        plant = chosen[index]
        leg = float(np.linalg.norm(stops[index] - here))
        total += leg
        plan.append({"id": plant.id, "row": plant.row, "expected_ripe": int(ripe_estimates[plant.id]),
                     "position": [round(v, 6) for v in plant.position], "leg_distance": round(leg, 6)})
        here = stops[index]
    back = float(np.linalg.norm(start - here))
    return {
        "workstation": [round(v, 6) for v in scene.workstation.center],
        "distance": "straight line in x-y between the workstation centre and the pots, m (obstacles not routed around)",
        "min_ripe": min_ripe,
        "stops": plan,
        "return_distance": round(back, 6),
        "total_distance": round(total + back, 6),
        "total_expected_ripe": int(sum(stop["expected_ripe"] for stop in plan)),
    }
