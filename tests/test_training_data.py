"""The training loader's augmentation keeps every target a valid box on a valid image."""

from __future__ import annotations

from pathlib import Path

import pytest

torch = pytest.importorskip("torch")


def test_augmented_samples_keep_their_boxes_inside_an_image_of_unit_range(tiny_dataset: Path):
    from renderloop.perception.training.data import PepperBoxes

    plain, augmented = PepperBoxes(tiny_dataset, "train", augment=False), PepperBoxes(tiny_dataset, "train", augment=True)
    torch.manual_seed(0)
    changed = 0
    for _ in range(6):
        for index in range(len(augmented)):
            image, target = augmented[index]
            height, width = image.shape[-2:]
            assert image.dtype == torch.float32 and 0.0 <= float(image.min()) and float(image.max()) <= 1.0
            boxes = target["boxes"]
            assert len(boxes) == len(target["labels"])
            assert bool(((boxes[:, 2] > boxes[:, 0]) & (boxes[:, 3] > boxes[:, 1])).all())
            assert bool(((boxes[:, :2] >= 0) & (boxes[:, 2:3] <= width) & (boxes[:, 3:4] <= height)).all())
            reference = plain[index][0]
            changed += image.shape != reference.shape or not torch.equal(image, reference)
    assert changed > 0  # the augmentation does something
