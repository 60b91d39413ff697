"""A user's own labelled photos train the detector too: the paper's last step, renders first, then a few real photos."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conftest import _fruit_image, cli, jittered_model
from renderloop.perception.detector import Detector
from renderloop.perception.training.ssd import export_onnx


@pytest.fixture(scope="module")
def photo_folder(tmp_path_factory) -> tuple[Path, Path]:
    """Six 'photos' with one category, `pepper`, that names no ripeness (like most real sets), and their COCO file."""
    root = tmp_path_factory.mktemp("photos")
    rng = np.random.default_rng(11)
    images, annotations = [], []
    for number in range(6):
        image, objects = _fruit_image(rng)
        image.save(root / f"p{number}.png")
        images.append({"id": number, "file_name": f"p{number}.png", "width": 96, "height": 72})
        for (x0, y0, x1, y1), _ in objects:
            annotations.append({"id": len(annotations), "image_id": number, "category_id": 7, "bbox": [x0, y0, x1 - x0, y1 - y0]})
    coco = root.parent / f"{root.name}.json"
    coco.write_text(json.dumps({"images": images, "annotations": annotations, "categories": [{"id": 7, "name": "pepper"}]}))
    return root, coco


def test_a_detector_fine_tuned_on_labelled_photos_changes_and_exports(monkeypatch, capsys, photo_folder, tmp_path: Path):
    folder, coco = photo_folder
    start = tmp_path / "start.onnx"
    export_onnx(jittered_model(3), start)
    tuned = tmp_path / "tuned.onnx"
    code, stdout, stderr = cli(monkeypatch, capsys, "train", "--photos", str(folder), "--coco", str(coco), "--photo-class", "ripe",
                               "--init", str(start), "--out", str(tuned), "--epochs", "1", "--batch-size", "3",
                               "--learning-rate", "1e-3", "--warmup-steps", "1", "--loader-workers", "0", "--device", "cpu")
    assert code == 0, stderr
    assert "train: wrote" in stdout
    record = json.loads(tuned.with_suffix(".json").read_text())
    assert record["photos"] == {"folder": str(folder), "coco": str(coco), "fallback_class": "ripe"}
    assert record["datasets"] == [] and record["train_images"] == 6 and len(record["history"]) == 1
    rgb = (np.random.default_rng(4).random((72, 96, 3)) * 255).astype(np.uint8)
    before, after = Detector(start).raw(rgb)[1], Detector(tuned).raw(rgb)[1]
    assert after.shape == before.shape and not np.allclose(after, before, atol=1e-4)  # two steps moved it


def test_photos_whose_categories_name_no_ripeness_need_a_class(monkeypatch, capsys, photo_folder, tmp_path: Path):
    folder, coco = photo_folder
    code, _, stderr = cli(monkeypatch, capsys, "train", "--photos", str(folder), "--coco", str(coco), "--out", str(tmp_path / "m.onnx"))
    assert code == 2
    assert stderr.strip().splitlines() == [f"renderloop: error: --coco {coco}: its categories name no ripeness (ripe, red, "
                                           "yellow, orange, unripe, green); give --photo-class ripe or unripe"]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("arguments", "message"), [
    (["--photos", "PHOTOS"], "--photos and --coco go together: the photo folder and its COCO labels"),
    (["--photos", "PHOTOS", "--coco", "COCO", "--photo-class", "red"], "--photo-class red: choose from ripe, unripe"),
    ([], "give a dataset folder made by `renderloop dataset`, or --photos with --coco, to train on"),
])
def test_photo_options_that_do_not_fit_are_one_line(monkeypatch, capsys, photo_folder, tmp_path: Path, arguments, message):
    folder, coco = photo_folder
    arguments = [{"PHOTOS": str(folder), "COCO": str(coco)}.get(a, a) for a in arguments]
    code, _, stderr = cli(monkeypatch, capsys, "train", *arguments, "--out", str(tmp_path / "m.onnx"))
    assert code == 2 and stderr.strip().splitlines() == [f"renderloop: error: {message}"]
    assert list(tmp_path.iterdir()) == []
