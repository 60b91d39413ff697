"""Which labelled fruit has a default box to learn from? The share of labelled boxes that no default box of a detector
overlaps at IoU 0.5 or more, by backbone and square input size, on a rendered dataset's split and on labelled photos.

SSD trains a box's class from the default boxes it overlaps at IoU 0.5 and more (torchvision's matcher also gives
each labelled box its best default box, however low: a "low-quality match"), so a fruit that no default box covers
at 0.5 is learned from one weak match at most. The labelled boxes are scaled to the square input as the detector
squeezes a frame (aspect not kept); the default boxes are those `renderloop train` builds
(`perception/training/ssd.py`), read off a network built without weights. Nothing trains or runs a network on the
images: the figures are geometry only, the same for any weights.

    .venv/bin/python benchmarks/anchor_coverage.py [--dataset DIR --split val] [--photos DIR --coco FILE]
        [--backbones mobilenet-v3,efficientnet-lite0-s8] [--sizes 320,448] [--name anchor_coverage]

Rendered fruit count from --min-side px on their shorter side (the held-out scans' smallest bin, 20 px); bins as
`detector_passes.py`'s. Photos: every labelled box, binned by its shorter side against the photo's.
Writes `benchmarks/results/NAME.json`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from common import as_table, save_result

from renderloop.config.training import BACKBONES
from renderloop.perception.photo_score import read_labels

COVERED = 0.5  # IoU: what SSD's matcher counts as a positive default box
RENDER_SIDES = ((20, 30), (30, 50), (50, 100), (100, None))  # px, a fruit's shorter side in its frame
PHOTO_SIDES = ((0.0, 0.25), (0.25, 0.5), (0.5, None))  # a fruit's shorter side against the photo's shorter side


def default_boxes_of(backbone: str, size: int) -> np.ndarray:
    """(A, 4) x0 y0 x1 y1 in px of the `size` square input: the default boxes a detector of `backbone` trains with."""
    import torch

    from renderloop.perception.training.ssd import build_model, default_boxes

    from torchvision.models.detection.image_list import ImageList  # after renderloop's torchvision import

    model = build_model(backbone, pretrained=False, train_size=size).eval()
    with torch.no_grad():
        dummy = torch.zeros(1, 3, size, size)
        features = list(model.backbone(dummy).values())
        return default_boxes(size, backbone)(ImageList(dummy, [(size, size)]), features)[0].clamp(0, size).numpy()


def best_iou(boxes: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """Each box's highest IoU with any default box."""
    x0 = np.maximum(boxes[:, None, 0], anchors[None, :, 0])
    y0 = np.maximum(boxes[:, None, 1], anchors[None, :, 1])
    x1 = np.minimum(boxes[:, None, 2], anchors[None, :, 2])
    y1 = np.minimum(boxes[:, None, 3], anchors[None, :, 3])
    inter = np.clip(x1 - x0, 0, None) * np.clip(y1 - y0, 0, None)
    area = lambda b: (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])  # noqa: E731
    return (inter / (area(boxes)[:, None] + area(anchors)[None, :] - inter)).max(axis=1)


def rendered(dataset: Path, split: str, min_side: float) -> list[tuple[np.ndarray, int, int, float]]:
    """Each target fruit's box, its frame's width and height, and its shorter side in px."""
    from renderloop.perception.training.data import read_coco

    coco = read_coco(dataset / "annotations" / f"instances_{split}.json")
    sizes = {image["id"]: (image["width"], image["height"]) for image in coco["images"]}
    found = []
    for ann in coco["annotations"]:
        x, y, w, h = ann["bbox"]
        if not ann["iscrowd"] and min(w, h) >= min_side:
            found.append((np.array([x, y, x + w, y + h], float), *sizes[ann["image_id"]], min(w, h)))
    return found


def photographed(folder: Path, coco: Path) -> list[tuple[np.ndarray, int, int, float]]:
    """Each labelled box, its photo's width and height, and its shorter side against the photo's."""
    return [(box, image.width, image.height, min(box[2] - box[0], box[3] - box[1]) / min(image.width, image.height))
            for image in read_labels(coco, folder).images for box in image.boxes]


def uncovered(fruit: list, anchors: np.ndarray, size: int, sides: tuple) -> dict:
    """The share of `fruit` with no default box at IoU COVERED, overall and per bin of `sides`."""
    boxes = np.array([box * size / np.array([w, h, w, h]) for box, w, h, _ in fruit]).reshape(-1, 4)
    missed = np.concatenate([best_iou(boxes[i:i + 256], anchors) for i in range(0, len(boxes), 256)]) < COVERED
    side = np.array([s for *_, s in fruit])
    out = {"boxes": len(fruit), "uncovered": round(float(missed.mean()), 3)}
    for low, high in sides:
        inside = (side >= low) & (side < (np.inf if high is None else high))
        out[f"{low:g}-{high:g}" if high is not None else f"over {low:g}"] = (
            round(float(missed[inside].mean()), 3) if inside.any() else None)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", type=Path, help="a folder made by `renderloop dataset` or `dataset-from-runs`")
    parser.add_argument("--split", default="val", choices=("train", "val"))
    parser.add_argument("--min-side", type=float, default=20.0, help="px, a rendered fruit's shorter side at least")
    parser.add_argument("--photos", type=Path, help="a folder of labelled photos (with --coco)")
    parser.add_argument("--coco", type=Path)
    parser.add_argument("--backbones", default="mobilenet-v3,efficientnet-lite0-s8")
    parser.add_argument("--sizes", default="320,448", help="square inputs, px")
    parser.add_argument("--name", default="anchor_coverage")
    args = parser.parse_args()
    backbones, sizes = args.backbones.split(","), [int(s) for s in args.sizes.split(",")]
    if unknown := [b for b in backbones if b not in BACKBONES]:
        parser.error(f"--backbones: {unknown[0]!r} is not one of {', '.join(BACKBONES)}")
    if (args.photos is None) != (args.coco is None) or (args.dataset is None and args.photos is None):
        parser.error("give --dataset, or --photos with --coco, or both")
    sources = []  # (table key, what the fruit are, the fruit, their bins)
    if args.dataset is not None:
        sources.append(("renders", f"{args.dataset.name} {args.split}, {args.min_side:g} px and up",
                        rendered(args.dataset, args.split, args.min_side), RENDER_SIDES))
    if args.photos is not None:
        sources.append(("photos", "labelled photos", photographed(args.photos, args.coco), PHOTO_SIDES))
    records: dict[str, list[dict]] = {key: [] for key, *_ in sources}
    for backbone in backbones:
        for size in sizes:
            anchors = default_boxes_of(backbone, size)
            for key, name, fruit, sides in sources:
                records[key].append({"source": name, "backbone": backbone, "input_px": size,
                                     "default_boxes": len(anchors), **uncovered(fruit, anchors, size, sides)})
                print(records[key][-1], flush=True)
    figures = {"covered_iou": COVERED}
    for key, name, fruit, sides in sources:
        bins = [k for k in records[key][0] if k not in ("source", "backbone", "input_px", "default_boxes", "boxes",
                                                         "uncovered")]
        unit = " px" if key == "renders" else " of the photo"
        columns = {"backbone": "backbone", "input_px": "input, px", "default_boxes": "default boxes", "boxes": "fruit",
                   "uncovered": "no default box at IoU 0.5", **{b: f"uncovered, {b}{unit}" for b in bins}}
        figures[key] = {"source": name, "records": records[key], "table": as_table(records[key], columns)}
    save_result(args.name, figures)

if __name__ == "__main__":
    main()
