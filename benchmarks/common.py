"""What the benchmark scripts share: how repeats are summarised, and the scan-like camera pose."""

from __future__ import annotations

import statistics

import numpy as np

from renderloop.robot.kinematics import look_at


def summary(values: list[float]) -> dict[str, float]:
    """Median with min and max, so the noise of the machine stays visible."""
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def scan_poses(scene, count: int) -> list[np.ndarray]:
    """Camera poses like the scan's: 0.44 m from a bearing plant, aimed at its centroid."""
    poses = []
    for plant in [p for p in scene.plants if p.bearing][:count]:
        target = np.array([plant.position[0], plant.position[1], (plant.position[2] + plant.pot.height + plant.bounds.max[2]) / 2])
        poses.append(look_at(target + np.array([-0.44, 0.05, 0.1]), target))
    return poses
