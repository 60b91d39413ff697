"""Box geometry shared by the detector, the merging of its passes, the scoring and the labels: size, overlap and NMS."""

from __future__ import annotations

import numpy as np


def shorter_side(box: tuple[float, float, float, float]) -> float:
    """The shorter side of one x0 y0 x1 y1 box: what decides whether a box is big enough to find or to keep."""
    return min(box[2] - box[0], box[3] - box[1])


def box_area(boxes: np.ndarray) -> np.ndarray:
    return (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])


def intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Area shared by each box of (N, 4) with each of (M, 4), x0 y0 x1 y1: an (N, M) matrix."""
    top_left = np.maximum(a[:, None, :2], b[None, :, :2])
    bottom_right = np.minimum(a[:, None, 2:], b[None, :, 2:])
    size = np.clip(bottom_right - top_left, 0, None)
    return size[..., 0] * size[..., 1]


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU matrix of boxes (N, 4) and (M, 4), x0 y0 x1 y1."""
    inter = intersection(a, b)
    return inter / np.maximum(box_area(a)[:, None] + box_area(b)[None, :] - inter, np.finfo(inter.dtype).tiny)


def nms(boxes: np.ndarray, scores: np.ndarray, iou_threshold: float) -> np.ndarray:
    """Greedy NMS: indices of kept boxes by decreasing score (stable for ties)."""
    order = np.argsort(-scores, kind="stable")
    iou = box_iou(boxes[order], boxes[order])
    keep = np.ones(len(order), dtype=bool)
    for i in range(len(order)):
        if keep[i]:
            keep[i + 1 :] &= iou[i, i + 1 :] <= iou_threshold
    return order[keep]
