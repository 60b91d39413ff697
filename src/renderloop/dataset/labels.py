"""Boxes of the visible part of each pepper, from an instance mask, with the rules for doubtful fruit.

A box is the extent of the pepper's mask pixels (pixel edges: x1 = last column + 1).
Two kinds of fruit are kept as `ignore` instead of labels: tiny ones (a side under
MIN_SIDE pixels) that no detector at 320 px can be asked to find, and fruit mostly
hidden behind leaves (under MIN_VISIBLE of the silhouette that would be in the image
without occluders), whose few pixels do not look like a pepper. torchvision's SSD
has no ignore regions, so training simply does not make them targets; the COCO
files mark them iscrowd, which COCO evaluation ignores. Fruit cut by the image border are not occluded: the silhouette is clipped
to the image first.
"""

from __future__ import annotations

import numpy as np
from matplotlib.path import Path as PolygonPath
from scipy.spatial import ConvexHull, QhullError

from renderloop.perception.scoring import mask_boxes
from renderloop.render.camera import Intrinsics
from renderloop.scene.model import Pepper, Scene
from renderloop.scene.plant_meshes import plant_meshes

MIN_SIDE = 6  # px at the dataset's 320 px width
MIN_VISIBLE = 0.25
LABELS = ("ripe", "unripe")  # COCO category ids 1 and 2


def label_of(pepper: Pepper) -> str:
    return "ripe" if pepper.ripe else "unripe"


def pepper_vertices(scene: Scene) -> dict[int, np.ndarray]:
    """Pepper id -> the vertices of its mesh in the world: the silhouettes' hulls are made of them."""
    vertices = {}
    for plant in scene.plants:
        vertices.update({k: m.vertices for k, m in plant_meshes(plant, scene.peppers_of(plant.id)).peppers.items()})
    return vertices


def silhouette_pixels(vertices: np.ndarray, pose: np.ndarray, intrinsics: Intrinsics, near: float) -> int | None:
    """Pixels of the image inside the convex hull of the projected mesh; None when part of it is behind the near plane."""
    local = (np.asarray(vertices) - pose[:3, 3]) @ pose[:3, :3]
    if np.any(local[:, 2] <= near):
        return None
    uv = intrinsics.project(local)
    try:
        hull = uv[ConvexHull(uv).vertices]
    except QhullError:
        return 0
    x0, y0 = np.maximum(np.floor(hull.min(axis=0)).astype(int), 0)
    x1 = min(int(np.ceil(hull[:, 0].max())), intrinsics.width - 1)
    y1 = min(int(np.ceil(hull[:, 1].max())), intrinsics.height - 1)
    if x1 < x0 or y1 < y0:
        return 0
    xs, ys = np.meshgrid(np.arange(x0, x1 + 1), np.arange(y0, y1 + 1))
    return int(PolygonPath(hull).contains_points(np.column_stack([xs.ravel(), ys.ravel()])).sum())


def pepper_boxes(mask: np.ndarray, peppers: dict[int, Pepper], meshes: dict[int, np.ndarray], pose: np.ndarray,
                 intrinsics: Intrinsics, near: float, min_side: float = MIN_SIDE) -> list[dict]:
    """One record per pepper seen in `mask`: its box, label, visible pixels and visible fraction, and whether it is ignored."""
    pixels = np.bincount(mask.ravel())
    records = []
    for pepper_id, box in mask_boxes(mask).items():
        silhouette = silhouette_pixels(meshes[pepper_id], pose, intrinsics, near)
        visible = pixels[pepper_id] / silhouette if silhouette else 1.0
        tiny = min(box[2] - box[0], box[3] - box[1]) < min_side
        records.append({
            "pepper_id": pepper_id, "bbox": list(box), "label": label_of(peppers[pepper_id]), "pixels": int(pixels[pepper_id]),
            "visible_fraction": round(min(visible, 1.0), 4),
            "ignore": "tiny" if tiny else "occluded" if visible < MIN_VISIBLE else None,
        })
    return records
