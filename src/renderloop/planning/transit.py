"""Collision-free transit between scan lines: shortest paths on a 2D occupancy grid.

At scan altitude every table (with its plants) and the workstation is a wall, so
the UAV routes in the plane. Obstacles are inflated by the robot's footprint radius
(rotor tips, or the arm, which sweeps round the body as it yaws), so any path
through free cells keeps the whole robot clear at any yaw. Dijkstra runs on the
8-connected grid (scipy's csgraph); the cell path is then shortened to the few
corners that see each other in a straight line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from renderloop.errors import UserError
from renderloop.scene.model import Scene

CELL = 0.05  # m


@dataclass(frozen=True)
class OccupancyGrid:
    free: np.ndarray  # (nx, ny) bool
    origin: np.ndarray  # world x, y of cell (0, 0)'s centre

    def cell(self, point: np.ndarray) -> tuple[int, int]:
        index = np.round((np.asarray(point[:2]) - self.origin) / CELL).astype(int)
        return int(index[0]), int(index[1])

    def center(self, cell: tuple[int, int]) -> np.ndarray:
        return self.origin + CELL * np.asarray(cell, dtype=float)

    def is_free(self, point: np.ndarray) -> bool:
        i, j = self.cell(point)
        return 0 <= i < self.free.shape[0] and 0 <= j < self.free.shape[1] and bool(self.free[i, j])

    def segment_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        steps = max(2, int(math.ceil(np.linalg.norm(np.asarray(b[:2]) - a[:2]) / (CELL / 2))) + 1)
        return all(self.is_free(a[:2] + t * (np.asarray(b[:2]) - a[:2])) for t in np.linspace(0.0, 1.0, steps))


def occupancy_grid(scene: Scene, radius: float) -> OccupancyGrid:
    """Free cells: inside the walls and at least `radius` from every table and the workstation."""
    length, width, _ = scene.room
    xs = np.arange(-length / 2 + CELL / 2, length / 2, CELL)
    ys = np.arange(-width / 2 + CELL / 2, width / 2, CELL)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    free = (np.abs(gx) <= length / 2 - radius) & (np.abs(gy) <= width / 2 - radius)
    boxes = [(row.table.center, row.table.size) for row in scene.rows]
    boxes.append((scene.workstation.center, scene.workstation.size))
    for center, size in boxes:
        dx = np.maximum(np.abs(gx - center[0]) - size[0] / 2, 0.0)
        dy = np.maximum(np.abs(gy - center[1]) - size[1] / 2, 0.0)
        free &= np.hypot(dx, dy) >= radius
    return OccupancyGrid(free=free, origin=np.array([xs[0], ys[0]]))


def _graph(grid: OccupancyGrid) -> coo_matrix:
    nx, ny = grid.free.shape
    index = np.arange(nx * ny).reshape(nx, ny)
    rows, cols, weights = [], [], []
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
        src = index[max(0, -di) : nx - max(0, di), max(0, -dj) : ny - max(0, dj)]
        dst = index[max(0, di) : nx - max(0, -di), max(0, dj) : ny - max(0, -dj)]
        both = grid.free.ravel()[src] & grid.free.ravel()[dst]
        rows.append(src[both])
        cols.append(dst[both])
        weights.append(np.full(int(both.sum()), CELL * math.hypot(di, dj)))
    src, dst, data = np.concatenate(rows), np.concatenate(cols), np.concatenate(weights)
    edges = (np.concatenate([data, data]), (np.concatenate([src, dst]), np.concatenate([dst, src])))
    return coo_matrix(edges, shape=(nx * ny, nx * ny))


class TransitPlanner:
    def __init__(self, scene: Scene, radius: float):
        self.grid = occupancy_grid(scene, radius)
        self.graph = _graph(self.grid).tocsr()
        self.radius = radius

    def route(self, start: np.ndarray, goal: np.ndarray) -> list[np.ndarray]:
        """Corner points (x, y) strictly between start and goal of a shortest collision-free route."""
        for name, point in (("start", start), ("goal", goal)):
            if not self.grid.is_free(point):
                raise UserError(
                    f"planner: transit {name} ({point[0]:.2f}, {point[1]:.2f}) is within {self.radius:.2f} m "
                    "of a table, the workstation or a wall (increase the greenhouse's aisles or planner.distance)"
                )
        if self.grid.segment_free(start, goal):
            return []
        ny = self.grid.free.shape[1]
        source, target = (i * ny + j for i, j in (self.grid.cell(start), self.grid.cell(goal)))
        _, predecessors = dijkstra(self.graph, indices=source, return_predecessors=True)
        if predecessors[target] < 0:
            raise UserError(f"planner: no collision-free transit from ({start[0]:.2f}, {start[1]:.2f}) to ({goal[0]:.2f}, {goal[1]:.2f})")
        cells = [target]
        while cells[-1] != source:
            cells.append(int(predecessors[cells[-1]]))
        path = [np.asarray(start[:2], float)] + [self.grid.center(divmod(c, ny)) for c in reversed(cells[1:-1])] + [np.asarray(goal[:2], float)]
        corners, anchor = [], 0
        while anchor < len(path) - 1:
            reach = len(path) - 1
            while reach > anchor + 1 and not self.grid.segment_free(path[anchor], path[reach]):
                reach -= 1
            if reach < len(path) - 1:
                corners.append(path[reach])
            anchor = reach
        return corners
