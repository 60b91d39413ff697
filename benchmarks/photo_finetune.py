"""What a few of your own labelled photos buy: the paper's last step, apart from everything else.

Splits a labelled photo set (a COCO file and its folder, as `renderloop score-photos` reads them) into two fixed
halves by image (the images sorted by file name, every second one to each half), fine-tunes a detector on the first
half (`renderloop train --photos ... --init MODEL`), and scores it and the model it started from on the second half
(`renderloop score-photos`), side by side. The fine-tuned model is an experiment: it is written under --work, never
into the package, and every other figure of the project stays synthetic-only.

    .venv/bin/python benchmarks/photo_finetune.py PHOTOS --coco LABELS.json --work /tmp/finetune [--init shipped]
        [--photo-class ripe] [--epochs 8] [--name photo_finetune]

Saves benchmarks/results/NAME.json, the model card's "Apart" table.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from common import save_result

RENDERLOOP = [sys.executable, "-m", "renderloop"]


def split_halves(coco: dict) -> tuple[dict, dict]:
    """The COCO file's images in two halves, alternately by sorted file name, each with its own annotations."""
    ordered = sorted(coco["images"], key=lambda image: image["file_name"])
    halves = []
    for half in (ordered[0::2], ordered[1::2]):
        ids = {image["id"] for image in half}
        halves.append({**coco, "images": half, "annotations": [a for a in coco["annotations"] if a["image_id"] in ids]})
    return halves[0], halves[1]


def score(folder: Path, coco: Path, model: Path, out: Path) -> dict:
    subprocess.run([*RENDERLOOP, "score-photos", str(folder), "--coco", str(coco), "--out", str(out), "--model", str(model),
                    "--force"], check=True)
    return json.loads((out / "score.json").read_text())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("photos", type=Path)
    parser.add_argument("--coco", type=Path, required=True)
    parser.add_argument("--work", type=Path, required=True, help="folder for the halves, the model and the scores")
    parser.add_argument("--init", default="shipped", help="the synthetic-only model to start from (default: the shipped one)")
    parser.add_argument("--photo-class", default="ripe", help="class of boxes whose category names no ripeness")
    parser.add_argument("--epochs", type=int, default=8)
    parser.add_argument("--learning-rate", type=float, default=3e-4)
    parser.add_argument("--name", default="photo_finetune", help="Results file: benchmarks/results/NAME.json.")
    args = parser.parse_args()

    from renderloop.perception.detector import shipped_model

    args.work.mkdir(parents=True, exist_ok=True)
    train_half, test_half = split_halves(json.loads(args.coco.read_text(encoding="utf-8")))
    train_coco, test_coco = args.work / "train_half.json", args.work / "test_half.json"
    train_coco.write_text(json.dumps(train_half))
    test_coco.write_text(json.dumps(test_half))
    start = shipped_model() if args.init == "shipped" else Path(args.init)
    tuned = args.work / "photo_tuned.onnx"
    began = time.perf_counter()
    subprocess.run([*RENDERLOOP, "train", "--photos", str(args.photos), "--coco", str(train_coco), "--photo-class",
                    args.photo_class, "--init", str(start), "--out", str(tuned), "--epochs", str(args.epochs),
                    "--learning-rate", str(args.learning_rate), "--warmup-steps", "20", "--device", "cpu"], check=True)
    minutes = (time.perf_counter() - began) / 60
    figures = {}
    for name, model in (("synthetic_only", start), ("photo_tuned", tuned)):
        agnostic = score(args.photos, test_coco, model, args.work / f"score_{name}")["class_agnostic"]
        figures[name] = {key: value for key, value in agnostic.items() if key != "curve"}
    result = {"init": args.init, "train_images": len(train_half["images"]), "test_images": len(test_half["images"]),
              "test_boxes": len(test_half["annotations"]), "epochs": args.epochs, "train_minutes": round(minutes, 1), **figures}
    print(json.dumps(result, indent=1))
    save_result(args.name, result)


if __name__ == "__main__":
    main()
