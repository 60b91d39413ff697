"""Boxes of the visible part of each pepper, from an instance mask, with the rules for doubtful fruit.

A box is the extent of the pepper's mask pixels (pixel edges: x1 = last column + 1).
Two kinds of fruit are kept as `ignore` instead of labels: tiny ones (a side under
MIN_SIDE pixels) that no detector at 320 px can be asked to find, and small fruit mostly
hidden behind leaves (under MIN_VISIBLE of the silhouette that would be in the image
without occluders), whose few pixels do not look like a pepper. A hidden fruit whose
visible part spans the scoring's findable size (`perception.scoring.MIN_SIDE` a side)
is a target all the same: the scoring asks for it, so training must (`ignore_reason`).
torchvision's SSD has no ignore regions, so training simply does not make ignored fruit
targets; the COCO files mark them iscrowd, which COCO evaluation ignores. Fruit cut by
the image border are not occluded: the silhouette is clipped to the image first.

The neighbouring rows' fruit are real peppers in the picture too, labelled by the same
rules (`neighbour_fruit_boxes`); left unlabelled they would teach the detector that a
pepper behind the scanned row is background. Their masks share one id, so their pixels
are told apart by their copies' projected meshes and the frame's depth.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.path import Path as PolygonPath
from scipy.spatial import ConvexHull, QhullError

from renderloop.perception.boxes import shorter_side
from renderloop.perception.scoring import MIN_SIDE as FINDABLE_SIDE, mask_boxes
from renderloop.render.camera import Intrinsics
from renderloop.scene.model import NEIGHBOUR_FRUIT_ID, Pepper, Scene
from renderloop.scene.plant_meshes import plant_meshes

MIN_SIDE = 6  # px at the dataset's 320 px width
MIN_VISIBLE = 0.25
DEPTH_TOLERANCE = 0.01  # m: a pixel's depth may lie this far outside its fruit's mesh (the mesh's facets, the depth's precision)
LABELS = ("ripe", "unripe")  # COCO category ids 1 and 2


def label_of(pepper: Pepper) -> str:
    return "ripe" if pepper.ripe else "unripe"


def pepper_vertices(scene: Scene) -> dict[int, np.ndarray]:
    """Pepper id -> the vertices of its mesh in the world: the silhouettes' hulls are made of them."""
    vertices = {}
    for plant in scene.plants:
        vertices.update({k: m.vertices for k, m in plant_meshes(plant, scene.peppers_of(plant.id)).peppers.items()})
    return vertices


def _silhouette(vertices: np.ndarray, pose: np.ndarray, intrinsics: Intrinsics,
                near: float) -> tuple[np.ndarray, int, int] | None:
    """The image pixels inside the convex hull of the projected mesh, as a mask over its bounding box and the box's
    top-left pixel (x0, y0); an empty mask off the image or for a degenerate hull; None when part of the mesh is
    behind the near plane."""
    local = (np.asarray(vertices) - pose[:3, 3]) @ pose[:3, :3]
    if np.any(local[:, 2] <= near):
        return None
    uv = intrinsics.project(local)
    try:
        hull = uv[ConvexHull(uv).vertices]
    except QhullError:
        return np.zeros((0, 0), dtype=bool), 0, 0
    x0, y0 = np.maximum(np.floor(hull.min(axis=0)).astype(int), 0)
    x1 = min(int(np.ceil(hull[:, 0].max())), intrinsics.width - 1)
    y1 = min(int(np.ceil(hull[:, 1].max())), intrinsics.height - 1)
    if x1 < x0 or y1 < y0:
        return np.zeros((0, 0), dtype=bool), 0, 0
    xs, ys = np.meshgrid(np.arange(x0, x1 + 1), np.arange(y0, y1 + 1))
    inside = PolygonPath(hull).contains_points(np.column_stack([xs.ravel(), ys.ravel()])).reshape(xs.shape)
    return inside, int(x0), int(y0)


def silhouette_pixels(vertices: np.ndarray, pose: np.ndarray, intrinsics: Intrinsics, near: float) -> int | None:
    """Pixels of the image inside the convex hull of the projected mesh; None when part of it is behind the near plane."""
    silhouette = _silhouette(vertices, pose, intrinsics, near)
    return None if silhouette is None else int(silhouette[0].sum())


def ignore_reason(box: Sequence[float], visible: float, min_side: float) -> str | None:
    """Why a fruit is no training target, or None: "tiny" (a side under `min_side` px) or "occluded" (under
    MIN_VISIBLE of its silhouette visible and its visible box under the findable size a side)."""
    side = shorter_side(box)
    return "tiny" if side < min_side else "occluded" if visible < MIN_VISIBLE and side < FINDABLE_SIDE else None


def relabelled(record: dict) -> dict:
    """A rendered image's label record (`renderloop dataset`, tiny under MIN_SIDE) with each fruit's `ignore` as
    `ignore_reason` gives it from the box and visible fraction the record holds: a set labelled by an earlier rule,
    brought to this one without rendering it again."""
    return {**record, "peppers": [{**p, "ignore": ignore_reason(p["bbox"], p["visible_fraction"], MIN_SIDE)}
                                  for p in record["peppers"]]}


def _record(pepper_id: int | None, box: tuple[int, int, int, int], pepper: Pepper, pixels: int, visible: float,
            min_side: float) -> dict:
    visible = round(min(visible, 1.0), 4)  # as stored, so that `relabelled` decides as this does
    return {
        "pepper_id": pepper_id, "bbox": list(box), "label": label_of(pepper), "pixels": pixels,
        "visible_fraction": visible, "ignore": ignore_reason(box, visible, min_side),
    }


def pepper_boxes(mask: np.ndarray, peppers: dict[int, Pepper], meshes: dict[int, np.ndarray], pose: np.ndarray,
                 intrinsics: Intrinsics, near: float, min_side: float = MIN_SIDE) -> list[dict]:
    """One record per pepper seen in `mask`: its box, label, visible pixels and visible fraction, and whether it is ignored."""
    pixels = np.bincount(mask.ravel())
    records = []
    for pepper_id, box in mask_boxes(mask).items():
        silhouette = silhouette_pixels(meshes[pepper_id], pose, intrinsics, near)
        visible = pixels[pepper_id] / silhouette if silhouette else 1.0
        records.append(_record(pepper_id, box, peppers[pepper_id], int(pixels[pepper_id]), visible, min_side))
    return records


def neighbour_fruit_boxes(mask: np.ndarray, depth: np.ndarray, fruit: list[tuple[Pepper, np.ndarray]], pose: np.ndarray,
                          intrinsics: Intrinsics, near: float, min_side: float = MIN_SIDE) -> list[dict]:
    """One record per fruit of the neighbouring rows seen in `mask` (`pepper_id` None), with the rules of
    `pepper_boxes`. The mask marks them all NEIGHBOUR_FRUIT_ID, so each such pixel goes to the fruit (of `fruit`:
    its pepper and world vertices, `renderloop.scene.objects.neighbour_fruit`) whose projected silhouette holds it
    and whose depth span holds the pixel's depth, the nearest when several do; pixels no fruit explains stay
    unlabelled."""
    marked = mask == NEIGHBOUR_FRUIT_ID
    if not marked.any():
        return []
    owner = np.full(mask.shape, -1, dtype=np.int64)
    nearest, farthest = float(depth[marked].min()) - DEPTH_TOLERANCE, float(depth[marked].max()) + DEPTH_TOLERANCE
    nearest_first = []
    for k, (_, vertices) in enumerate(fruit):
        z = (np.asarray(vertices) - pose[:3, 3]) @ pose[:3, 2]  # along the optical axis: the depth a frame stores
        if z.max() >= nearest and z.min() <= farthest:  # else no marked pixel can be this fruit's
            nearest_first.append((float(z.min()), float(z.max()), k))
    silhouettes = {}
    for low, high, k in sorted(nearest_first):
        silhouette = _silhouette(fruit[k][1], pose, intrinsics, near)
        if silhouette is None or not silhouette[0].any():
            continue
        inside, x0, y0 = silhouette
        region = (slice(y0, y0 + inside.shape[0]), slice(x0, x0 + inside.shape[1]))
        seen = depth[region]
        mine = inside & marked[region] & (owner[region] < 0) & (seen >= low - DEPTH_TOLERANCE) & (seen <= high + DEPTH_TOLERANCE)
        owner[region][mine] = k
        silhouettes[k] = int(inside.sum())
    records = []
    for k in np.unique(owner[owner >= 0]).tolist():
        rows, cols = np.nonzero(owner == k)
        box = (int(cols.min()), int(rows.min()), int(cols.max()) + 1, int(rows.max()) + 1)
        records.append(_record(None, box, fruit[k][0], len(rows), len(rows) / silhouettes[k], min_side))
    return records
