"""COCO detection files of the dataset: one per split, categories `ripe` (1) and `unripe` (2).

Boxes are [x, y, width, height] in pixels from the top-left image corner (COCO);
ignored fruit (tiny or mostly hidden) are kept with iscrowd 1, which COCO
evaluation treats as "don't care" and training leaves out.
"""

from __future__ import annotations

from pathlib import Path

from renderloop.dataset.labels import LABELS
from renderloop.io.atomic import write_json

CATEGORIES = [{"id": i + 1, "name": name, "supercategory": "pepper"} for i, name in enumerate(LABELS)]
SPLITS = ("train", "val")


def coco_split(records: list[dict], split: str) -> dict:
    images, annotations = [], []
    for image_id, record in enumerate(records):
        if record["split"] != split:
            continue
        images.append({"id": image_id, "file_name": record["image"], "width": record["width"], "height": record["height"]})
        for pepper in record["peppers"]:
            x0, y0, x1, y1 = pepper["bbox"]
            annotations.append({
                "id": len(annotations) + 1, "image_id": image_id, "category_id": LABELS.index(pepper["label"]) + 1,
                "bbox": [x0, y0, x1 - x0, y1 - y0], "area": pepper["pixels"], "iscrowd": int(pepper["ignore"] is not None),
                "pepper_id": pepper["pepper_id"],
            })
    return {"images": images, "annotations": annotations, "categories": CATEGORIES}


def write_coco(directory: Path, records: list[dict]) -> None:
    for split in SPLITS:
        write_json(Path(directory) / f"instances_{split}.json", coco_split(records, split))
