"""Merging the boxes of several detector passes over one frame: the whole frame, its mirror image and its windows.

One fruit is usually boxed by more than one pass; a false box seldom is, because each
pass sees the scene at another scale, crop or handedness. So overlapping boxes (IoU >= FUSE_IOU,
whatever their class) are one object, boxed and labelled by its best box, scored by the
noisy-OR of each pass's best score for it, 1 - prod(1 - s): the chance that at least one
pass is right, were they independent. Agreement lifts a fruit that each pass saw at
0.4; a box only one pass saw keeps its score. It beat class-wise NMS over the same boxes
at every rate of false detections (docs/stages/perception.md).
"""

from __future__ import annotations

import numpy as np

from renderloop.perception.boxes import box_iou

FUSE_IOU = 0.4  # one fruit boxed by two passes differs more than NMS's 0.55 allows: crops cut it differently


def fuse(boxes: np.ndarray, scores: np.ndarray, passes: np.ndarray, iou_threshold: float = FUSE_IOU
         ) -> tuple[np.ndarray, np.ndarray]:
    """Groups boxes (N, 4) greedily by score: the best free box takes every free box that overlaps it.
    Returns each group's best box (indices into the inputs) and the group's fused score, best first.
    A pass's second box in a group adds nothing: it is that pass's duplicate, not a second opinion."""
    order = np.argsort(-scores, kind="stable")
    overlaps = box_iou(boxes[order], boxes[order]) >= iou_threshold
    np.fill_diagonal(overlaps, True)  # a degenerate box still groups with itself
    free = np.ones(len(order), dtype=bool)
    leaders, fused = [], []
    for i in range(len(order)):
        if not free[i]:
            continue
        group = order[free & overlaps[i]]
        free &= ~overlaps[i]
        _, first_of_pass = np.unique(passes[group], return_index=True)  # group is by score: the pass's best
        leaders.append(order[i])
        fused.append(1.0 - np.prod(1.0 - scores[group[first_of_pass]]))
    rank = np.argsort(-np.asarray(fused), kind="stable")
    return np.asarray(leaders, dtype=int)[rank], np.asarray(fused, dtype=float)[rank]
