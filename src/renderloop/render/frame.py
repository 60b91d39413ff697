"""What every render backend returns for one camera pose."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class RenderedFrame:
    rgb: np.ndarray  # (H, W, 3) uint8, sRGB
    depth: np.ndarray  # (H, W) float32, planar depth along the optical axis, m; 0 = no return or outside the clip range
    # (H, W) uint16: the pepper id of scene.json where a pepper is the first surface hit, NEIGHBOUR_FRUIT_ID on a
    # neighbouring row's fruit, else 0
    mask: np.ndarray
    timings: dict[str, float] = field(default_factory=dict)  # seconds
