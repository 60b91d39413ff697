"""The harvest plan: which plants to bring to the manipulator workstation, and in what order.

In the reference work's greenhouse (paper, "Simulation results") mobile robots carry
plant containers to a stationary manipulator workstation, and the mission planner
acts on the per-plant counts. Here the plan is one round trip from the workstation
through every plant expected to bear at least `min_ripe` ripe fruit: a travelling
salesman tour built greedily (nearest neighbour) and improved by 2-opt until no
segment reversal shortens it. Fewer than 40 plants make 2-opt instant and usually
optimal or within a few per cent.

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


def two_opt(start: np.ndarray, stops: np.ndarray, order: list[int]) -> list[int]:
    """Reverse tour segments while that shortens the closed tour (workstation fixed at both ends)."""
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
