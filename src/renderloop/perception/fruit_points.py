"""One 3D point per detected pepper: the fruit's pixels inside its box, found by depth.

A box around a pepper also holds leaves in front of it and whatever lies behind it,
but the detected fruit is what its box is mostly about: of all depth windows as deep
as a pepper's visible skin, the one holding most of the points in the box's central
part is the fruit (the nearest such window on ties). The centroid of the points in
it is returned: a point on the visible skin, as in the reference work. The nearest
surface would often be a leaf in front of the fruit (docs/stages/perception.md).

That centroid lies in front of the fruit's centre: pixels sample the visible half of a
roughly round fruit evenly in projection, so their mean depth is two thirds of a radius
short of the centre. `fruit_point` moves it that far along the viewing ray, with the
radius read off the box width at the fruit's depth (a box narrowed by a leaf gives a
smaller radius, so the move errs short rather than through the fruit; no radius is
taken above a pepper's).

A ripe fruit also differs from what surrounds it by colour: red, orange and yellow
skin has at least as much red as green and far more red than blue, which no leaf,
stem, sky, wall or floor has. When the box of a ripe detection holds enough such
pixels, only they are searched for the fruit's depth window; a stem or leaf across
the fruit then cannot pull the point off it. Green fruit look like leaves, so their
boxes use depth alone.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from renderloop.perception.pointcloud import organised_cloud, to_world
from renderloop.rundir.models import Detection, DetectionFrame

if TYPE_CHECKING:
    from renderloop.config import DetectorConfig
    from renderloop.perception.detector import Detector
    from renderloop.render.camera import Intrinsics

FRUIT_DEPTH = 0.06  # m of depth a pepper's visible skin spans
CENTRAL = 0.6  # fraction of the box's width and height taken as its centre
MIN_POINTS = 5
BIN = 0.01  # m, depth histogram resolution
CENTRE_BEHIND_SKIN = 2 / 3  # radii: the mean depth of a sphere's visible half, area-weighted in projection
MAX_RADIUS = 0.05  # m: sweet peppers are at most 10 cm wide; a wide box on something else moves no further
RIPE_CHROMA = 20  # 8-bit red minus blue: most of a red fruit's pixels pass, almost none of the rest (docs/stages/perception.md)


def ripe_coloured(rgb: np.ndarray) -> np.ndarray:
    """Pixels (..., 3 uint8) of a ripe pepper's colour: red at least green, and well above blue."""
    r, g, b = (rgb[..., i].astype(np.int16) for i in range(3))
    return (r >= g) & (r - b >= RIPE_CHROMA)


def fruit_point(cloud: np.ndarray, box: tuple[float, float, float, float], fx: float,
                fruit_pixels: np.ndarray | None = None) -> np.ndarray | None:
    """The fruit's centre (optical frame) estimated from its surface inside `box` = (x0, y0, x1, y1) pixels, or None;
    fx is the focal length in pixels; fruit_pixels (H x W bool), when given, marks the pixels of the fruit's colour."""
    height, width, _ = cloud.shape
    x0, y0, x1, y1 = box
    cx, cy, hw, hh = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) * CENTRAL / 2, (y1 - y0) * CENTRAL / 2
    cols = slice(max(0, int(np.floor(cx - hw))), min(width, int(np.ceil(cx + hw)) + 1))
    rows = slice(max(0, int(np.floor(cy - hh))), min(height, int(np.ceil(cy + hh)) + 1))
    points = cloud[rows, cols].reshape(-1, 3)
    usable = np.isfinite(points[:, 2])
    if fruit_pixels is not None:
        coloured = usable & fruit_pixels[rows, cols].reshape(-1)
        if coloured.sum() >= MIN_POINTS:
            usable = coloured
    points = points[usable]
    if len(points) < MIN_POINTS:
        return None
    depth = points[:, 2]
    edges = np.arange(depth.min(), depth.max() + BIN, BIN)
    counts, _ = np.histogram(depth, bins=np.append(edges, edges[-1] + BIN))
    window = max(1, int(round(FRUIT_DEPTH / BIN)))
    support = np.convolve(counts, np.ones(window, dtype=int), mode="full")[window - 1 :]  # support[i]: bins i .. i+window-1
    start = edges[int(np.argmax(support))]
    keep = (depth >= start) & (depth < start + FRUIT_DEPTH)
    if keep.sum() < MIN_POINTS:
        return None
    skin = points[keep].mean(axis=0)
    radius = min(0.5 * (x1 - x0) * skin[2] / fx, MAX_RADIUS)
    return skin + CENTRE_BEHIND_SKIN * radius * skin / np.linalg.norm(skin)


def find_fruit(detector: Detector, rgb: np.ndarray, depth: np.ndarray, pose: np.ndarray, settings: DetectorConfig,
               intrinsics: Intrinsics) -> list[Detection]:
    """The detector's boxes on one frame, each with its fruit point in the world (None without depth returns)."""
    cloud, ripe_pixels = organised_cloud(depth, intrinsics), ripe_coloured(rgb)
    detections = []
    for found in detector.search(rgb, settings):
        point = fruit_point(cloud, found.bbox, intrinsics.fx, ripe_pixels if found.label == "ripe" else None)
        world = None if point is None else tuple(round(float(v), 5) for v in to_world(point, pose))
        box = found.to_json()
        detections.append(Detection(bbox=tuple(box["bbox"]), score=box["score"], label=box["label"], position=world))
    return detections


def detect_frame(detector: Detector, index: int, timestamp: float, image: str, rgb: np.ndarray, depth: np.ndarray,
                 pose: np.ndarray, settings: DetectorConfig, intrinsics: Intrinsics) -> DetectionFrame:
    """Frame `index` of a scan (its colour file named `image` in the run) with the fruit found on it."""
    return DetectionFrame(index=index, timestamp=round(float(timestamp), 6), image=image,
                          detections=find_fruit(detector, rgb, depth, pose, settings, intrinsics))
