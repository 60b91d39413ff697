"""A RealSense-like depth sensor: noise growing with z², missing returns at edges and out of range.

sigma(z) = sigma_at_1m * z² (metres): the stereo error grows with the square of the
distance. The RotorS D435 plugin squares an RMS before using it as sigma; we take
sigma itself from the config. Pixels on depth discontinuities (where the stereo
matcher sees two surfaces) lose their return with probability `edge_dropout`.
"""

from __future__ import annotations

import numpy as np

from renderloop.config import DepthNoiseConfig

EDGE_JUMP = 0.05  # m between neighbouring pixels that makes an edge


def depth_edges(depth: np.ndarray) -> np.ndarray:
    """Pixels with a neighbour (4-connected) whose depth differs by more than EDGE_JUMP or has no return."""
    padded = np.pad(depth, 1, mode="edge")
    centre = padded[1:-1, 1:-1]
    edges = np.zeros(depth.shape, dtype=bool)
    for neighbour in (padded[:-2, 1:-1], padded[2:, 1:-1], padded[1:-1, :-2], padded[1:-1, 2:]):
        edges |= (np.abs(neighbour - centre) > EDGE_JUMP) | ((neighbour == 0) != (centre == 0))
    return edges


def sensor_depth(depth: np.ndarray, config: DepthNoiseConfig, clip: tuple[float, float], rng: np.random.Generator) -> np.ndarray:
    """The depth a sensor would report for the true planar `depth` (0 = no return)."""
    valid = depth > 0
    noisy = depth + rng.standard_normal(depth.shape).astype(np.float32) * (config.sigma_at_1m * depth**2)
    dropped = depth_edges(depth) & (rng.random(depth.shape) < config.edge_dropout)
    keep = valid & ~dropped & (noisy >= clip[0]) & (noisy <= clip[1])
    return np.where(keep, noisy, 0.0).astype(np.float32)
