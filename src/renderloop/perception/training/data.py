"""The COCO training set as torch samples, with SSD's augmentation.

Augmentation is the SSD recipe (torchvision's v2 transforms carry the boxes along):
photometric distortion, zoom out (smaller fruit on a padded canvas), IoU-constrained
random crops (larger fruit, fruit cut by the border), horizontal flips; then blur and JPEG
compression, each on a share of the images. Sensor noise is not added here: a training set's
views through the colour-sensor model (`render/sensor.py`) carry the real camera's measured
noise, and noise on top of them would be many times the real frames'. Fruit
marked iscrowd (tiny or mostly hidden, see `renderloop.dataset.labels`) are not targets.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import torch
from PIL import Image

from renderloop.errors import UserError
from renderloop.io.images import check_image, open_image
from renderloop.perception.detector import CLASSES
from renderloop.perception.training.torch_support import import_torchvision

import_torchvision()
from torchvision import tv_tensors
from torchvision.transforms import v2

FILL = (110, 115, 110)  # zoom-out canvas: the greenhouse's mean grey-green
# JPEG through Pillow: torchvision's own JPEG transform needs the compiled image ops a CPU-only torch lacks.
JPEG_SHARE, JPEG_QUALITY = 0.3, (40, 95)


def jpeg_compressed(picture: Image.Image, quality: int) -> Image.Image:
    """The picture as a camera's JPEG of this quality would give it back: blocks, ringing, smeared colour."""
    buffer = io.BytesIO()
    picture.save(buffer, format="JPEG", quality=quality)
    buffer.seek(0)
    return Image.open(buffer).convert("RGB")


def read_coco(path: Path) -> dict:
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        data["images"], data["annotations"]
    except FileNotFoundError:
        raise UserError(f"{path}: no such file (make the dataset with `renderloop dataset`)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError):
        raise UserError(f"{path}: not a COCO detection file") from None
    return data


class _Boxes(torch.utils.data.Dataset):
    """Images with their target boxes (x0, y0, x1, y1 in pixels), class ids (1 ripe, 2 unripe) and COCO image ids (what
    the validation's results are matched to the labels by), as SSD's samples."""

    def __init__(self, samples: list[tuple[Path, list[list[float]], list[int], int]], augment: bool) -> None:
        self.samples, self.augment = samples, augment
        geometry = [v2.RandomPhotometricDistort(p=0.5), v2.RandomZoomOut(fill=FILL, side_range=(1.0, 2.0), p=0.3),
                    v2.RandomIoUCrop(), v2.RandomHorizontalFlip(),
                    v2.RandomApply([v2.GaussianBlur(5, sigma=(0.1, 1.5))], p=0.2)] if augment else []
        self.transform = v2.Compose([*geometry, v2.ToDtype(torch.float32, scale=True), v2.SanitizeBoundingBoxes()])

    def __len__(self) -> int:
        return len(self.samples)

    def __getitem__(self, index: int) -> tuple[torch.Tensor, dict]:
        path, boxes, labels, image_id = self.samples[index]
        picture = open_image(path, "RGB")
        if self.augment and float(torch.rand(())) < JPEG_SHARE:
            picture = jpeg_compressed(picture, int(torch.randint(JPEG_QUALITY[0], JPEG_QUALITY[1] + 1, ())))
        image = tv_tensors.Image(v2.functional.pil_to_tensor(picture))
        target = {
            "boxes": tv_tensors.BoundingBoxes(torch.tensor(boxes, dtype=torch.float32).reshape(-1, 4), format="XYXY",
                                              canvas_size=tuple(image.shape[-2:])),
            "labels": torch.tensor(labels, dtype=torch.int64),
            "image_id": image_id,
        }
        if len(boxes) == 0:  # the IoU crop needs a box to keep; a fruitless view is used as it is
            image, target = v2.ToDtype(torch.float32, scale=True)(image, target)
            return image, target
        return self.transform(image, target)


class PepperBoxes(_Boxes):
    """One split of a dataset made by `renderloop dataset`."""

    def __init__(self, root: Path, split: str, augment: bool) -> None:
        self.root = Path(root)
        self.annotation_file = self.root / "annotations" / f"instances_{split}.json"
        coco = read_coco(self.annotation_file)
        self.images = coco["images"]
        # Headers only (cheap: nothing is decoded), here in the trainer's process: a UserError raised in a DataLoader
        # worker comes back with the worker's traceback in its message, not as one line. Truncated data still
        # shows only when a worker decodes it.
        for number, image in enumerate(self.images):
            if not isinstance(image, dict) or not isinstance(image.get("file_name"), str) or "id" not in image:
                raise UserError(f"{self.annotation_file}: images.{number}: needs an id and a file_name")
            check_image(self.root / image["file_name"])
        targets: dict[int, list[dict]] = {image["id"]: [] for image in self.images}
        for ann in coco["annotations"]:
            if not ann["iscrowd"]:
                targets[ann["image_id"]].append(ann)
        super().__init__([(self.root / image["file_name"],
                           [[x, y, x + w, y + h] for x, y, w, h in (a["bbox"] for a in targets[image["id"]])],
                           [a["category_id"] for a in targets[image["id"]]], image["id"]) for image in self.images], augment)


class PhotoBoxes(_Boxes):
    """A user's own labelled photos (a COCO file and its photo folder, as `renderloop score-photos` reads them), for the
    last step of the paper's recipe: renders first, then a few real photos. A box's class is its category's ripeness
    (a category named ripe, red, yellow, orange, unripe or green), else `fallback` (one class for a set that names
    none); with neither, the photos cannot be trained on."""

    def __init__(self, folder: Path, coco: Path, fallback: str | None, augment: bool) -> None:
        from renderloop.perception.photo_score import read_labels

        self.annotation_file = Path(coco)
        labels = read_labels(coco, folder)
        if not labels.by_class and fallback is None:
            raise UserError(f"--coco {coco}: its categories name no ripeness (ripe, red, yellow, orange, unripe, green); "
                            "give --photo-class ripe or unripe")
        ids = {name: number + 1 for number, name in enumerate(CLASSES)}
        super().__init__([(image.path, image.boxes.tolist(), [ids[label or fallback] for label in image.classes], image.id)
                          for image in labels.images], augment)


def collate(batch: list) -> tuple[list, list]:
    images, targets = zip(*batch)
    return list(images), list(targets)
