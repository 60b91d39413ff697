"""The detector: torch and ONNX agree, post-processing is torchvision's, training resumes, bad models are refused."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import onnx
import pytest
import torch
from PIL import Image, ImageDraw

from renderloop.errors import UserError
from renderloop.io.atomic import write_json
from renderloop.perception.boxes import nms
from renderloop.perception.detector import Detector, postprocess, to_input
from renderloop.perception.training.ssd import DecodedSSD, build_model, export_onnx
from renderloop.perception.training.torch_support import import_torchvision
from renderloop.perception.training.train import TrainSettings, _schedule, train_detector

from conftest import jittered_model

torchvision = import_torchvision()


def _fruit_image(rng: np.random.Generator, size=(96, 72)) -> tuple[Image.Image, list[tuple[list[int], int]]]:
    """Green clutter with red (ripe) and dark green (unripe) blobs at known places."""
    image = Image.new("RGB", size, (60, 110, 50))
    draw = ImageDraw.Draw(image)
    for _ in range(6):
        x, y = rng.integers(0, size[0]), rng.integers(0, size[1])
        draw.ellipse([x, y, x + 20, y + 8], fill=(40, 140, 40))
    objects = []
    for _ in range(int(rng.integers(1, 3))):
        w, h = int(rng.integers(12, 24)), int(rng.integers(14, 26))
        x, y = int(rng.integers(0, size[0] - w)), int(rng.integers(0, size[1] - h))
        ripe = bool(rng.random() < 0.6)
        draw.ellipse([x, y, x + w - 1, y + h - 1], fill=(200, 30, 20) if ripe else (20, 80, 20))
        objects.append(([x, y, x + w, y + h], 1 if ripe else 2))
    return image, objects


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("tiny")
    (root / "images").mkdir()
    (root / "annotations").mkdir()
    rng = np.random.default_rng(0)
    for split, count in (("train", 8), ("val", 3)):
        images, annotations = [], []
        for i in range(count):
            image, objects = _fruit_image(rng)
            name = f"images/{split}{i}.jpg"
            image.save(root / name, quality=95)
            images.append({"id": i, "file_name": name, "width": 96, "height": 72})
            for box, label in objects:
                x0, y0, x1, y1 = box
                annotations.append({"id": len(annotations) + 1, "image_id": i, "category_id": label,
                                    "bbox": [x0, y0, x1 - x0, y1 - y0], "area": (x1 - x0) * (y1 - y0), "iscrowd": 0})
        write_json(root / "annotations" / f"instances_{split}.json",
                   {"images": images, "annotations": annotations,
                    "categories": [{"id": 1, "name": "ripe"}, {"id": 2, "name": "unripe"}]})
    return root


def test_numpy_nms_equals_torchvision_nms():
    rng = np.random.default_rng(2)
    corners = rng.uniform(0, 80, (300, 2))
    boxes = np.column_stack([corners, corners + rng.uniform(5, 40, (300, 2))]).astype(np.float32)
    scores = rng.random(300).astype(np.float32)
    for threshold in (0.3, 0.55, 0.8):
        expected = torchvision.ops.nms(torch.from_numpy(boxes), torch.from_numpy(scores), threshold).numpy()
        assert np.array_equal(nms(boxes.astype(float), scores.astype(float), threshold), expected)


def test_postprocessing_equals_torchvisions_ssd():
    """Same head outputs through torchvision's SSD post-processing and ours. Random head outputs,
    not a random network's: those score many anchors exactly alike, and ties at the top-300 cut
    are broken arbitrarily by torch.topk."""
    model = build_model().eval()
    anchors = DecodedSSD(model).anchors
    generator = torch.Generator().manual_seed(6)
    head = {"bbox_regression": torch.randn(1, len(anchors), 4, generator=generator) * 0.5,
            "cls_logits": torch.randn(1, len(anchors), 3, generator=generator) * 2.0}
    with torch.no_grad():
        expected = model.postprocess_detections(head, [anchors], [(320, 320)])[0]
        boxes = torchvision.ops.clip_boxes_to_image(model.box_coder.decode_single(head["bbox_regression"][0], anchors), (320, 320))
        scores = torch.softmax(head["cls_logits"][0], dim=-1)
    ours = postprocess(boxes.numpy(), scores.numpy(), 640, 480, score_threshold=0.0)
    keep = expected["scores"].numpy() > 0.01
    assert len(ours) == keep.sum() > 50
    assert np.allclose([d.bbox for d in ours], expected["boxes"].numpy()[keep] * [2, 1.5, 2, 1.5], atol=1e-3)
    assert np.allclose([d.score for d in ours], expected["scores"].numpy()[keep], atol=1e-6)
    assert [d.label for d in ours] == [("ripe", "unripe")[k - 1] for k in expected["labels"].numpy()[keep]]
    # a threshold applied before NMS keeps exactly the detections above it
    above = [d for d in ours if d.score >= 0.5]
    assert len(above) > 10 and postprocess(boxes.numpy(), scores.numpy(), 640, 480, score_threshold=0.5) == above


def test_onnx_model_gives_the_torch_models_outputs(tmp_path: Path):
    model = jittered_model(4)
    path = tmp_path / "model.onnx"
    export_onnx(model, path)
    detector = Detector(path)
    rgb = (np.random.default_rng(5).random((240, 320, 3)) * 255).astype(np.uint8)
    boxes, scores = detector.raw(rgb)
    with torch.no_grad():
        expected_boxes, expected_scores = DecodedSSD(model).eval()(torch.from_numpy(to_input(rgb)))
    assert np.allclose(boxes, expected_boxes.numpy(), atol=2e-5)
    assert np.allclose(scores, expected_scores.numpy(), atol=2e-5)
    found = detector.detect(rgb, 0.3)
    assert all(0 <= d.bbox[0] <= d.bbox[2] <= 320 and 0 <= d.bbox[1] <= d.bbox[3] <= 240 for d in found)


def test_learning_rate_warms_up_linearly_then_decays_to_zero_over_the_run():
    factor = _schedule(TrainSettings(epochs=2, warmup_steps=10), steps_per_epoch=25)
    rates = [factor(step) for step in range(50)]
    assert rates[:10] == pytest.approx([(step + 1) / 10 for step in range(10)])
    assert rates[10] == 1.0 and all(a > b for a, b in zip(rates[10:], rates[11:]))
    assert rates[-1] < 0.01
    assert _schedule(TrainSettings(warmup_steps=0), steps_per_epoch=5)(0) == 1.0  # no warm-up: full rate at once


def test_training_checkpoints_resumes_and_exports(tiny_dataset: Path, tmp_path: Path):
    out = tmp_path / "model.onnx"
    settings = TrainSettings(epochs=2, batch_size=4, warmup_steps=1)
    first = train_detector(tiny_dataset, out, TrainSettings(**{**settings.__dict__, "max_steps": 2}), device="cpu", workers=0, log=lambda _: None)
    assert [e["epoch"] for e in first["history"]] == [1]
    logged = []
    record = train_detector(tiny_dataset, out, settings, device="cpu", workers=0, log=logged.append)
    assert logged[0].startswith("resuming after epoch 1")
    assert [e["epoch"] for e in record["history"]] == [1, 2]
    assert {"map50", "map", "ap50_ripe", "ap50_unripe", "loss"} <= set(record["history"][-1])
    assert json.loads(out.with_suffix(".json").read_text())["train_images"] == 8
    detector = Detector(out)
    assert detector.detect(np.zeros((72, 96, 3), np.uint8), 0.0) is not None
    with pytest.raises(UserError, match="other settings"):
        train_detector(tiny_dataset, out, TrainSettings(epochs=3, batch_size=4), device="cpu", workers=0, log=lambda _: None)


def test_fine_tuning_starts_from_the_weights_of_a_checkpoint(tiny_dataset: Path, tmp_path: Path):
    first = tmp_path / "first.onnx"
    settings = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, max_steps=1)
    train_detector(tiny_dataset, first, settings, device="cpu", workers=0, log=lambda _: None)
    still = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, learning_rate=1e-7, max_steps=1)  # too small to move the weights
    tuned = tmp_path / "tuned.onnx"
    record = train_detector(tiny_dataset, tuned, still, device="cpu", workers=0, log=lambda _: None, init=first.with_suffix(".ckpt"))
    assert record["init"] == str(first.with_suffix(".ckpt"))
    rgb = (np.random.default_rng(1).random((240, 320, 3)) * 255).astype(np.uint8)
    assert np.allclose(Detector(tuned).raw(rgb)[1], Detector(first).raw(rgb)[1], atol=1e-3)
    junk = tmp_path / "junk.ckpt"
    junk.write_bytes(b"not a checkpoint")
    with pytest.raises(UserError, match="junk.ckpt: not a renderloop training checkpoint"):
        train_detector(tiny_dataset, tmp_path / "other.onnx", settings, device="cpu", workers=0, log=lambda _: None, init=junk)


def test_fine_tuning_starts_from_an_onnx_detector_whose_batch_norms_are_folded(tiny_dataset: Path, tmp_path: Path):
    exported = tmp_path / "exported.onnx"
    export_onnx(jittered_model(6), exported)  # batch norms with non-trivial statistics, folded by the exporter
    still = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, learning_rate=1e-7, max_steps=1)
    tuned = tmp_path / "tuned.onnx"
    record = train_detector(tiny_dataset, tuned, still, device="cpu", workers=0, log=lambda _: None, init=exported)
    assert record["frozen_batch_norms"] is True
    rgb = (np.random.default_rng(2).random((240, 320, 3)) * 255).astype(np.uint8)
    # the same function: the weights came back, and a training step did not move the frozen statistics
    for got, want in zip(Detector(tuned).raw(rgb), Detector(exported).raw(rgb)):
        assert np.allclose(got, want, atol=1e-3)
    other = tmp_path / "other.onnx"
    onnx.save(onnx.helper.make_model(onnx.helper.make_graph([], "empty", [], [])), str(other))
    with pytest.raises(UserError, match="other.onnx: 0 convolutions where the detector has 98"):
        train_detector(tiny_dataset, tmp_path / "x.onnx", still, device="cpu", workers=0, log=lambda _: None, init=other)


def test_several_datasets_train_together_and_are_scored_apart(tiny_dataset: Path, tmp_path: Path):
    second = tmp_path / "second"
    shutil.copytree(tiny_dataset, second)
    coco = json.loads((second / "annotations" / "instances_val.json").read_text())
    coco["images"], coco["annotations"] = coco["images"][:1], [a for a in coco["annotations"] if a["image_id"] == coco["images"][0]["id"]]
    write_json(second / "annotations" / "instances_val.json", coco)
    settings = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, max_steps=1)
    record = train_detector([tiny_dataset, second], tmp_path / "both.onnx", settings, device="cpu", workers=0, log=lambda _: None)
    assert record["train_images"] == 16 and record["val_images"] == [3, 1]
    scores = record["history"][-1]["val"]
    assert set(scores) == {str(tiny_dataset), str(second)}
    assert {k: record["history"][-1][k] for k in scores[str(tiny_dataset)]} == scores[str(tiny_dataset)]


def test_files_that_are_not_detectors_are_refused(tmp_path: Path):
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(UserError, match="junk.onnx: not an ONNX model"):
        Detector(junk)
    with pytest.raises(UserError, match="no such model file"):
        Detector(tmp_path / "missing.onnx")
    other = tmp_path / "other.onnx"
    torch.onnx.export(torch.nn.Linear(3, 2), (torch.zeros(1, 3),), str(other), input_names=["x"], dynamo=False)
    with pytest.raises(UserError, match="other.onnx: not a renderloop pepper detector"):
        Detector(other)


def test_training_imports_nothing_of_the_simulator_so_it_runs_where_blender_and_mujoco_are_not_installed():
    """A lab trains on a GPU machine that need not have bpy (Python 3.11 only) or MuJoCo: `renderloop train` reads
    JPEGs and COCO, so its imports stop at torch, pydantic and pycocotools (docs/stages/perception.md)."""
    import subprocess
    import sys

    simulator = ["bpy", "mujoco", "ray", "numba", "toppra", "rosbags", "rerun", "plotly", "OpenEXR", "sklearn", "scipy",
                 "matplotlib"]
    code = ("import sys, renderloop.cli, renderloop.perception.detector, renderloop.perception.training.train; "
            f"print([m for m in {simulator!r} if m in sys.modules])")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
