"""Fine-tuning data from flown runs: every chosen frame with the boxes of its mask, whole runs as validation."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from renderloop.dataset.build import claim_dataset
from renderloop.dataset.from_runs import dataset_from_runs
from renderloop.errors import UserError
from renderloop.perception.scoring import mask_boxes
from renderloop.render.frames import read_png
from renderloop.rundir.names import frame_name


def test_frames_of_runs_become_a_coco_set_with_the_masks_boxes(complete_run: Path, tmp_path: Path):
    frames = len(list((complete_run / "rgb").glob("*.png")))
    out = tmp_path / "flown"
    assert dataset_from_runs([complete_run, complete_run], out, every=2) == 2 * len(range(0, frames, 2))
    train = json.loads((out / "annotations" / "instances_train.json").read_text())
    val = json.loads((out / "annotations" / "instances_val.json").read_text())
    assert len(train["images"]) == len(val["images"]) == len(range(0, frames, 2))
    scored = 0
    for number, image in enumerate(train["images"]):
        record = json.loads((out / "labels" / Path(image["file_name"]).with_suffix(".json").name).read_text())
        assert record["frame"] == 2 * number and record["split"] == "train"
        mask = read_png(complete_run / "masks" / frame_name(record["frame"]), np.uint16)
        assert {p["pepper_id"]: tuple(p["bbox"]) for p in record["peppers"]} == mask_boxes(mask)
        with Image.open(out / image["file_name"]) as jpeg:
            assert jpeg.size == (image["width"], image["height"]) == (mask.shape[1], mask.shape[0])
        scored += len(record["peppers"])
    assert scored > 0
    assert (out / "preview.png").is_file()

    dataset_from_runs([complete_run, complete_run], out, every=frames)  # rewritten: no image of the larger set is left
    assert sorted(p.name for p in (out / "images").iterdir()) == ["000000.jpg", "000001.jpg"]


def test_runs_without_masks_or_a_rendered_dataset_are_refused_before_anything_is_written(complete_run: Path, tmp_path: Path):
    maskless = tmp_path / "maskless"
    shutil.copytree(complete_run, maskless)
    (maskless / "masks" / frame_name(0)).unlink()
    out = tmp_path / "flown"
    with pytest.raises(UserError, match=r"masks/000000.png: missing"):
        dataset_from_runs([complete_run, maskless], out)
    assert not out.exists()
    with pytest.raises(UserError, match="--val-runs 1"):
        dataset_from_runs([complete_run], out)
    rendered = claim_dataset(tmp_path / "rendered")  # a dataset folder `renderloop dataset` made
    (rendered / "dataset.json").write_text('{"seed": 0, "width": 320}')
    with pytest.raises(UserError, match="holds a rendered dataset"):
        dataset_from_runs([complete_run, complete_run], rendered)
