"""Random camera views of plants: where a scan camera could be, and wider.

The flown camera sees a plant from 0.3-0.5 m in its aisle; training views spread
distance, height, bearing and aim around that (and add a little roll, which a
tilting UAV gives its camera), so the detector meets fruit at every size, at the
image edges and half hidden, never only centred. A view is redrawn when the camera
would sit inside a plant's box, a table or below the table top.
"""

from __future__ import annotations

import math

import numpy as np

from renderloop.robot.kinematics import look_at
from renderloop.scene.model import Scene

DISTANCE = (0.3, 1.2)  # m from the plant's axis, horizontal; drawn closer more often, as scans are
BEARING = math.radians(60.0)  # spread around the row's normal
HEIGHT = (-0.15, 0.35)  # m about the canopy centre
MAX_UPWARD = math.radians(20.0)  # scans look level or down; a little up is allowed
AIM = 0.3  # fraction of the canopy box the aim point may leave its centre by
ROLL = math.radians(8.0)
CLEARANCE = 0.05  # m between the camera and any plant box or table
MAX_TRIES = 200


def _roll(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _blocked(scene: Scene, position: np.ndarray) -> bool:
    for plant in scene.plants:
        if plant.bounds.contains(tuple(position), CLEARANCE):
            return True
    for row in scene.rows:
        center, size = np.asarray(row.table.center), np.asarray(row.table.size)
        half = size / 2 + CLEARANCE
        if np.all(np.abs(position[:2] - center[:2]) <= half[:2]) and position[2] <= size[2] + CLEARANCE:
            return True
    return False


def random_view(scene: Scene, rng: np.random.Generator, distance_range: tuple[float, float] = DISTANCE) -> np.ndarray:
    """T_world_optical of one random view of a random plant, `distance_range` m (horizontal) from its axis."""
    for _ in range(MAX_TRIES):
        plant = scene.plants[int(rng.integers(len(scene.plants)))]
        low, high = np.asarray(plant.bounds.min), np.asarray(plant.bounds.max)
        canopy_low = np.array([low[0], low[1], plant.position[2] + plant.pot.height])
        center, size = (canopy_low + high) / 2, high - canopy_low
        side = 0.0 if rng.random() < 0.5 else math.pi  # rows run along y: look from +x or -x
        bearing = side + rng.uniform(-BEARING, BEARING)
        distance = distance_range[0] + (distance_range[1] - distance_range[0]) * rng.random() ** 2
        camera = np.array([plant.position[0] + distance * math.cos(bearing), plant.position[1] + distance * math.sin(bearing),
                           center[2] + rng.uniform(*HEIGHT)])
        if _blocked(scene, camera):
            continue
        target = center + rng.uniform(-AIM, AIM, 3) * size
        if target[2] - camera[2] > math.tan(MAX_UPWARD) * math.hypot(*(target[:2] - camera[:2])):
            continue
        pose = look_at(camera, target)
        pose[:3, :3] = pose[:3, :3] @ _roll(rng.uniform(-ROLL, ROLL))
        return pose
    raise RuntimeError("no unobstructed camera position found around the plants")
