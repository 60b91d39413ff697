"""Do our rendered peppers look like peppers to a network that learned real ones? The share of rendered fruit that
EfficientNet-Lite0's own ImageNet classifier (the detector's default backbone with the head it was trained with, from
the same checkpoint) calls a bell pepper, beside the same share for real photographed peppers at the same sizes.

A crop is a fruit's box widened by a tenth each side, resized to 224x224: every fruit of a rendered dataset's labels
that is a target (not `iscrowd`), at least VISIBLE visible and at least --min-side px on its shorter side, up to
--crops of them drawn with --seed. Real crops are the labelled boxes of --photos (a COCO folder, as `score-photos`
reads it), each shrunk first to the shorter side of a rendered crop drawn at random (so the real fruit are seen at
the renders' sizes; the renders are 320x240, a photo's pepper a third of 416 px) and also at its own size. The
classifier only looks: nothing here trains, and no threshold or setting anywhere is chosen on the photos.

    .venv/bin/python benchmarks/pepper_look.py DATASET... [--photos DIR --coco FILE] [--crops 400] [--name pepper_look]

Writes `benchmarks/results/NAME.json`: per source, crops, top-1 and top-5 bell-pepper rate and the classes most often
named first; a dataset whose views went partly through the colour-sensor model (`--sensor`) also apart by that.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import numpy as np
from PIL import Image

from common import as_table, save_result

from renderloop.io.images import open_image
from renderloop.perception.photo_score import read_labels

BELL_PEPPER = 945  # ImageNet-1k's class index of "bell pepper"
VISIBLE = 0.7  # share of a rendered fruit's pixels in view
MARGIN = 0.1  # of the box's side, each way
SIDE = 224  # the classifier's input


def crop(picture: Image.Image, box, shrink_to: int | None = None) -> Image.Image:
    x0, y0, x1, y1 = box
    w, h = x1 - x0, y1 - y0
    part = picture.crop((x0 - MARGIN * w, y0 - MARGIN * h, x1 + MARGIN * w, y1 + MARGIN * h))
    if shrink_to is not None and shrink_to < min(w, h):
        scale = shrink_to / min(w, h)
        part = part.resize((max(1, round(part.width * scale)), max(1, round(part.height * scale))), Image.BILINEAR)
    return part.resize((SIDE, SIDE), Image.BILINEAR)


def rendered_boxes(dataset: Path, min_side: float) -> list[tuple[Path, tuple, str, bool]]:
    """Each target fruit's image, box, class and whether its view went through the colour-sensor model."""
    found = []
    for path in sorted((dataset / "labels").glob("*.json")):
        label = json.loads(path.read_text())
        for pepper in label["peppers"]:
            x0, y0, x1, y1 = pepper["bbox"]
            if pepper["ignore"] is None and pepper["visible_fraction"] >= VISIBLE and min(x1 - x0, y1 - y0) >= min_side:
                found.append((dataset / label["image"], (x0, y0, x1, y1), pepper["label"], bool(label.get("sensor"))))
    return found


class Classifier:
    def __init__(self) -> None:
        import torch

        from renderloop.perception.training.backbones import imagenet_logits, lite0_features, load_lite0

        from torchvision.models import MobileNet_V3_Large_Weights  # after renderloop's torchvision import

        self.torch, self.logits = torch, imagenet_logits
        self.features = lite0_features().eval()
        self.head = load_lite0(self.features).eval()
        self.names = MobileNet_V3_Large_Weights.IMAGENET1K_V1.meta["categories"]  # ImageNet-1k's, in index order

    def top5(self, crops: list[Image.Image]) -> list[list[int]]:
        batch = self.torch.from_numpy(np.stack([np.asarray(c, np.float32) for c in crops])).permute(0, 3, 1, 2)
        return self.logits(self.features, self.head, batch).topk(5, dim=1).indices.tolist()


def rates(classifier: Classifier, crops: list[Image.Image]) -> dict:
    tops = [top for start in range(0, len(crops), 32) for top in classifier.top5(crops[start:start + 32])]
    first = Counter(top[0] for top in tops)
    return {"crops": len(tops), "top1": round(sum(top[0] == BELL_PEPPER for top in tops) / max(1, len(tops)), 3),
            "top5": round(sum(BELL_PEPPER in top for top in tops) / max(1, len(tops)), 3),
            "named_first": [[classifier.names[index], count] for index, count in first.most_common(5)]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("datasets", nargs="+", type=Path, help="folders made by `renderloop dataset`")
    parser.add_argument("--photos", type=Path, help="a folder of labelled real photos (with --coco)")
    parser.add_argument("--coco", type=Path)
    parser.add_argument("--crops", type=int, default=400, help="crops drawn from each source")
    parser.add_argument("--min-side", type=float, default=30.0, help="px, a rendered fruit's shorter side at least")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--name", default="pepper_look")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    classifier = Classifier()
    records, render_sides = [], []
    for dataset in args.datasets:
        boxes = rendered_boxes(dataset, args.min_side)
        for label in ("ripe", "unripe"):
            chosen = [boxes[i] for i in rng.permutation(len(boxes)) if boxes[i][2] == label][:args.crops]
            render_sides += [min(b[2] - b[0], b[3] - b[1]) for _, b, _, _ in chosen]
            for through, part in (("", chosen), (", without the sensor model", [b for b in chosen if not b[3]]),
                                  (", through the sensor model", [b for b in chosen if b[3]])):
                if part and (not through or len(part) < len(chosen)):  # a split only where both halves are there
                    crops = [crop(open_image(path, "RGB"), box) for path, box, _, _ in part]
                    records.append({"source": f"{dataset.name} renders, {label}{through}", **rates(classifier, crops)})
                    print(records[-1], flush=True)
    if args.photos is not None:
        labels = read_labels(args.coco, args.photos)
        boxes = [(image.path, tuple(box)) for image in labels.images for box in image.boxes]
        chosen = [boxes[i] for i in rng.permutation(len(boxes))[:args.crops]]
        shrink = rng.choice(render_sides, size=len(chosen)) if render_sides else [None] * len(chosen)
        for case, sides in (("photos at the renders' sizes", shrink), ("photos at their own size", [None] * len(chosen))):
            crops = [crop(open_image(path, "RGB"), box, None if side is None else int(side))
                     for (path, box), side in zip(chosen, sides)]
            records.append({"source": case, **rates(classifier, crops)})
            print(records[-1], flush=True)
    columns = {"source": "crops of", "crops": "crops", "top1": "bell pepper, top-1", "top5": "bell pepper, top-5"}
    save_result(args.name, {"min_side_px": args.min_side, "visible": VISIBLE, "records": records,
                            "table": as_table(records, columns)})


if __name__ == "__main__":
    main()
