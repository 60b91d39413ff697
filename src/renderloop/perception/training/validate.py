"""COCO mAP of the torch model on a split, with pycocotools (the reference implementation)."""

from __future__ import annotations

import contextlib
import io

import numpy as np
import torch
from pycocotools.coco import COCO
from pycocotools.cocoeval import COCOeval

from renderloop.perception.detector import CLASSES
from renderloop.perception.training.data import PepperBoxes


@torch.no_grad()
def predictions(model: torch.nn.Module, dataset: PepperBoxes, device: torch.device) -> list[dict]:
    model.eval()
    results = []
    for index in range(len(dataset)):
        image, target = dataset[index]
        output = model([image.to(device)])[0]
        for box, score, label in zip(output["boxes"].cpu().tolist(), output["scores"].cpu().tolist(), output["labels"].cpu().tolist()):
            results.append({"image_id": target["image_id"], "category_id": int(label),
                            "bbox": [box[0], box[1], box[2] - box[0], box[3] - box[1]], "score": float(score)})
    return results


def _class_ap(precision: np.ndarray, iou_index: slice | int, class_index: int) -> float | None:
    """None for a class the split has no fruit of (NaN would not survive the JSON record)."""
    values = precision[iou_index, :, class_index, 0, -1]  # all areas, 100 detections
    values = values[values > -1]
    return float(values.mean()) if values.size else None


def coco_map(model: torch.nn.Module, dataset: PepperBoxes, device: torch.device) -> dict[str, float | None]:
    """mAP@0.5 and @0.5:0.95 over both classes, and AP@0.5 of each class."""
    results = predictions(model, dataset, device)
    with contextlib.redirect_stdout(io.StringIO()):  # pycocotools prints its progress
        truth = COCO(str(dataset.annotation_file))
        if not results:
            return {"map50": 0.0, "map": 0.0, **{f"ap50_{name}": 0.0 for name in CLASSES}}
        evaluation = COCOeval(truth, truth.loadRes(results), "bbox")
        evaluation.evaluate()
        evaluation.accumulate()
        evaluation.summarize()
    precision = evaluation.eval["precision"]
    scores = {"map": float(evaluation.stats[0]), "map50": float(evaluation.stats[1])}
    scores.update({f"ap50_{name}": _class_ap(precision, 0, i) for i, name in enumerate(CLASSES)})
    return scores
