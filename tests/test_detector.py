"""The detector: torch and ONNX agree, post-processing is torchvision's, training resumes, bad models are refused."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import onnx
import pytest
import torch

from renderloop.config.training import PREDATED
from renderloop.errors import UserError
from renderloop.io.atomic import write_json
from renderloop.perception.boxes import nms
from renderloop.perception.detector import Detector, postprocess, to_input
from renderloop.perception.training.graph import fold_pads_in_file
from renderloop.perception.training.ssd import DecodedSSD, build_model, export_onnx
from renderloop.perception.training.torch_support import import_torchvision
from renderloop.perception.training import train as train_module
from renderloop.perception.training.train import TrainSettings, _schedule, backbone_of_init, train_detector

from conftest import cli, jittered_model

torchvision = import_torchvision()
from torchvision.models.detection.image_list import ImageList  # noqa: E402 -- after import_torchvision's fix


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


@pytest.mark.parametrize("backbone", ["efficientnet-lite0", "efficientnet-lite0-s8"])
def test_onnx_model_gives_the_torch_models_outputs(tmp_path: Path, backbone: str):
    model = jittered_model(4, backbone)
    path = tmp_path / "model.onnx"
    export_onnx(model, path)
    detector = Detector(path)
    rgb = (np.random.default_rng(5).random((240, 320, 3)) * 255).astype(np.uint8)
    boxes, scores = detector.raw(rgb)
    with torch.no_grad():
        expected_boxes, expected_scores = DecodedSSD(model).eval()(torch.from_numpy(to_input(rgb)))
    assert np.allclose(boxes, expected_boxes.numpy(), atol=1e-3)  # pixels: float32 rounding through 17 pretrained blocks
    assert np.allclose(scores, expected_scores.numpy(), atol=2e-5)
    found = detector.detect(rgb, 0.3)
    assert all(0 <= d.bbox[0] <= d.bbox[2] <= 320 and 0 <= d.bbox[1] <= d.bbox[3] <= 240 for d in found)
    # the strided convolutions' asymmetric padding is in the convolutions (training/graph.py): nothing left to fold
    graph = onnx.load(str(path))
    assert "Pad" not in {node.op_type for node in graph.graph.node}
    assert fold_pads_in_file(path) == 0 and onnx.load(str(path)) == graph


def test_a_model_exported_with_a_larger_input_keeps_its_default_boxes_sizes_in_pixels(tmp_path: Path):
    model = jittered_model(4)
    trained, larger = DecodedSSD(model).anchors, DecodedSSD(model, 448).anchors
    assert len(larger) > len(trained)  # a finer grid of default boxes over the larger input

    def sizes(anchors: torch.Tensor, size: int) -> set:
        inside = (anchors[:, :2] > 0).all(1) & (anchors[:, 2:] < size).all(1)  # boxes clipped at the border are smaller
        return {tuple(v) for v in torch.round(anchors[inside, 2:] - anchors[inside, :2], decimals=2).tolist()}

    # every size the network trained with is there, the smallest still 0.04 of the trained input; only boxes that the
    # smaller input clipped at its border come whole as well
    assert sizes(trained, 320) <= sizes(larger, 448)
    assert min(w * h for w, h in sizes(larger, 448)) == pytest.approx(0.04 * 320 * 0.04 * 320, rel=1e-3)
    path = tmp_path / "model448.onnx"
    export_onnx(model, path, input_size=448)
    detector = Detector(path)
    assert detector.input_size == 448
    rgb = (np.random.default_rng(5).random((480, 640, 3)) * 255).astype(np.uint8)
    boxes, scores = detector.raw(rgb)
    with torch.no_grad():
        expected_boxes, expected_scores = DecodedSSD(model, 448).eval()(torch.from_numpy(to_input(rgb, 448)))
    assert np.allclose(boxes, expected_boxes.numpy(), atol=1e-3) and np.allclose(scores, expected_scores.numpy(), atol=2e-5)
    found = detector.detect(rgb, 0.3)
    assert found and all(0 <= d.bbox[0] <= d.bbox[2] <= 640 and 0 <= d.bbox[1] <= d.bbox[3] <= 480 for d in found)


def test_a_lower_match_iou_trains_a_fruit_from_more_default_boxes_and_the_smallest_fruit_from_its_best_one():
    from torchvision.ops import box_iou

    fruit = torch.tensor([[100.0, 100.0, 126.0, 126.0], [200.0, 40.0, 205.0, 45.0]])  # 26x26 px, and 5x5 px
    learners = {}
    for match_iou in (0.3, 0.5):
        model = build_model("mobilenet-v3", pretrained=False, match_iou=match_iou).eval()
        matched = model.proposal_matcher(box_iou(fruit, DecodedSSD(model).anchors))  # each default box's fruit, -1 none
        learners[match_iou] = [int((matched == i).sum()) for i in range(len(fruit))]
    assert learners[0.3][0] > learners[0.5][0] >= 2
    assert learners[0.3][1] == learners[0.5][1] == 1  # under every default box's IoU threshold: its best box alone


def test_a_checkpoint_from_before_a_setting_existed_resumes_only_at_what_it_trained_with(tiny_dataset: Path,
                                                                                          tmp_path: Path):
    out = tmp_path / "old.onnx"
    settings = TrainSettings(epochs=2, batch_size=4, warmup_steps=1, **PREDATED)
    train_detector(tiny_dataset, out, TrainSettings(**{**settings.model_dump(), "max_steps": 2}), device="cpu", workers=0,
                   log=lambda _: None)
    state = torch.load(out.with_suffix(".ckpt"), weights_only=True)
    for name in PREDATED:  # as a checkpoint written before the settings were
        del state["record"]["settings"][name]
    torch.save(state, out.with_suffix(".ckpt"))
    assert backbone_of_init(out.with_suffix(".ckpt")) == PREDATED["backbone"]
    for name in PREDATED:  # today's default is not what it trained with, and the refusal names the option
        today = TrainSettings().model_dump()[name]
        with pytest.raises(UserError, match=rf"other settings or data \(--{name.replace('_', '-')} {PREDATED[name]} "
                                            rf"\(this run: {today}\)\); give the same to resume it"):
            train_detector(tiny_dataset, out, TrainSettings(**{**settings.model_dump(), name: today}),
                           device="cpu", workers=0, log=lambda _: None)
    logged = []
    record = train_detector(tiny_dataset, out, settings, device="cpu", workers=0, log=logged.append)
    assert logged[0].startswith("resuming after epoch 1") and [e["epoch"] for e in record["history"]] == [1, 2]


def test_learning_rate_warms_up_linearly_then_decays_to_zero_over_the_run():
    factor = _schedule(TrainSettings(epochs=2, warmup_steps=10), steps_per_epoch=25)
    rates = [factor(step) for step in range(50)]
    assert rates[:10] == pytest.approx([(step + 1) / 10 for step in range(10)])
    assert rates[10] == 1.0 and all(a > b for a, b in zip(rates[10:], rates[11:]))
    assert rates[-1] < 0.01
    assert _schedule(TrainSettings(warmup_steps=0), steps_per_epoch=5)(0) == 1.0  # no warm-up: full rate at once


def test_training_checkpoints_resumes_and_exports(tiny_dataset: Path, tmp_path: Path, monkeypatch):
    out = tmp_path / "model.onnx"
    settings = TrainSettings(epochs=2, batch_size=4, warmup_steps=1)
    with monkeypatch.context() as patch:  # the first epoch in torch's default layout: a checkpoint of either layout resumes
        patch.setattr(train_module, "MEMORY_FORMAT", torch.contiguous_format)
        first = train_detector(tiny_dataset, out, TrainSettings(**{**settings.model_dump(), "max_steps": 2}), device="cpu", workers=0,
                               log=lambda _: None)
    assert [e["epoch"] for e in first["history"]] == [1]
    first_conv = "backbone.features.0.0.0.weight"
    assert torch.load(out.with_suffix(".ckpt"), weights_only=True)["model"][first_conv].is_contiguous()
    logged = []
    monkeypatch.setattr(train_module, "PROGRESS_BATCHES", 1)  # a progress line each batch of the resumed epoch
    record = train_detector(tiny_dataset, out, settings, device="cpu", workers=0, log=logged.append)
    assert logged[0].startswith("resuming after epoch 1")
    assert [line.split(", loss")[0] for line in logged[1:3]] == ["epoch 2: 1 of 2 batches", "epoch 2: 2 of 2 batches"]
    assert json.loads(logged[3])["epoch"] == 2
    resumed = torch.load(out.with_suffix(".ckpt"), weights_only=True)["model"][first_conv]
    assert resumed.is_contiguous(memory_format=torch.channels_last) and not resumed.is_contiguous()  # trained in NHWC
    assert [e["epoch"] for e in record["history"]] == [1, 2]
    assert {"map50", "map", "ap50_ripe", "ap50_unripe", "loss"} <= set(record["history"][-1])
    assert json.loads(out.with_suffix(".json").read_text())["train_images"] == 8
    detector = Detector(out)
    assert detector.input_size == 320 and detector.detect(np.zeros((72, 96, 3), np.uint8), 0.0) is not None
    # the finished run given another input size exports the same weights again, without training
    again = train_detector(tiny_dataset, out, settings, device="cpu", workers=0, log=lambda _: None, input_size=384)
    assert again["history"] == record["history"] and Detector(out).input_size == 384
    with pytest.raises(UserError, match="--input-size 330: give a multiple of 32 from 160 to 1280 px"):
        train_detector(tiny_dataset, out, settings, device="cpu", workers=0, log=lambda _: None, input_size=330)
    with pytest.raises(UserError, match="other settings"):
        train_detector(tiny_dataset, out, TrainSettings(epochs=3, batch_size=4), device="cpu", workers=0, log=lambda _: None)


def test_a_network_trained_at_a_larger_input_exports_at_that_size_with_the_same_default_box_sizes(tiny_dataset: Path,
                                                                                                   tmp_path: Path):
    out = tmp_path / "m384.onnx"
    settings = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, max_steps=1, train_size=384, backbone="mobilenet-v3")
    record = train_detector(tiny_dataset, out, settings, device="cpu", workers=0, log=lambda _: None)
    assert record["settings"]["train_size"] == 384 and record["input_size"] == 384
    state = torch.load(out.with_suffix(".ckpt"), weights_only=True)
    model = build_model("mobilenet-v3", pretrained=False, train_size=384)
    model.load_state_dict(state["model"])
    assert model.transform.fixed_size == (384, 384)
    # the default boxes it trained on are those the exported model decodes from
    model.eval()
    rgb = (np.random.default_rng(3).random((480, 640, 3)) * 255).astype(np.uint8)
    with torch.no_grad():
        trained = model.anchor_generator(ImageList(torch.zeros(1, 3, 384, 384), [(384, 384)]),
                                         list(model.backbone(torch.zeros(1, 3, 384, 384)).values()))[0]
        assert torch.allclose(trained, DecodedSSD(model, 384).anchors)
        expected = DecodedSSD(model, 384)(torch.from_numpy(to_input(rgb, 384)))
    detector = Detector(out)
    assert detector.input_size == 384
    assert all(np.allclose(got, want.numpy(), atol=1e-3) for got, want in zip(detector.raw(rgb), expected))
    # the narrowest box is still 0.04 of a 320 px input at a side ratio of 3 (12.8 px / sqrt 3), not of 384 px
    assert (trained[:, 2:] - trained[:, :2]).min().item() == pytest.approx(0.04 * 320 / 3 ** 0.5, rel=1e-4)
    with pytest.raises(UserError, match="other settings"):  # a run's training size is part of what it resumes
        train_detector(tiny_dataset, out, TrainSettings(**{**settings.model_dump(), "train_size": 320}), device="cpu",
                       workers=0, log=lambda _: None)


def test_fine_tuning_starts_from_the_weights_of_a_checkpoint(tiny_dataset: Path, tmp_path: Path):
    first = tmp_path / "first.onnx"
    settings = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, max_steps=1)
    train_detector(tiny_dataset, first, settings, device="cpu", workers=0, log=lambda _: None)
    still = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, learning_rate=1e-9, max_steps=1)  # too small to move the weights
    tuned = tmp_path / "tuned.onnx"
    record = train_detector(tiny_dataset, tuned, still, device="cpu", workers=0, log=lambda _: None, init=first.with_suffix(".ckpt"))
    assert record["init"] == str(first.with_suffix(".ckpt"))
    # the learned weights came back (the batch norms' running statistics go on averaging, as in any training step)
    before, after = (torch.load(path.with_suffix(".ckpt"), weights_only=True)["model"] for path in (first, tuned))
    learned = [key for key in before if not key.endswith(("running_mean", "running_var", "num_batches_tracked"))]
    assert all(torch.allclose(after[key], before[key], atol=1e-6) for key in learned)
    junk = tmp_path / "junk.ckpt"
    junk.write_bytes(b"not a checkpoint")
    with pytest.raises(UserError, match="junk.ckpt: not a renderloop training checkpoint"):
        train_detector(tiny_dataset, tmp_path / "other.onnx", settings, device="cpu", workers=0, log=lambda _: None, init=junk)


def test_fine_tuning_starts_from_an_onnx_detector_whose_batch_norms_are_folded(tiny_dataset: Path, tmp_path: Path):
    exported = tmp_path / "exported.onnx"
    export_onnx(jittered_model(6), exported)  # batch norms with non-trivial statistics, folded by the exporter
    still = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, learning_rate=1e-9, max_steps=1)
    tuned = tmp_path / "tuned.onnx"
    record = train_detector(tiny_dataset, tuned, still, device="cpu", workers=0, log=lambda _: None, init=exported)
    assert record["frozen_batch_norms"] is True
    rgb = (np.random.default_rng(2).random((240, 320, 3)) * 255).astype(np.uint8)
    # the same function: the weights came back, and a training step did not move the frozen statistics
    for got, want in zip(Detector(tuned).raw(rgb), Detector(exported).raw(rgb)):
        assert np.allclose(got, want, atol=1e-3)
    other = tmp_path / "other.onnx"
    onnx.save(onnx.helper.make_model(onnx.helper.make_graph([], "empty", [], [])), str(other))
    with pytest.raises(UserError, match="other.onnx: 0 convolutions where the detector has 89"):
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


def _fake_detector(path: Path, boxes: np.ndarray, scores: np.ndarray, input_type: int = onnx.TensorProto.FLOAT) -> Path:
    """An ONNX file with the detector's input and output names whose outputs are the given constants."""
    from onnx import helper, numpy_helper

    outputs = (("boxes", boxes), ("scores", scores))
    graph = helper.make_graph(
        [helper.make_node("Constant", [], [name], value=numpy_helper.from_array(value, name)) for name, value in outputs],
        "fake", [helper.make_tensor_value_info("images", input_type, [1, 3, 320, 320])],
        [helper.make_tensor_value_info(name, helper.np_dtype_to_tensor_dtype(value.dtype), value.shape) for name, value in outputs])
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=8), path)
    return path


BOXES = np.tile(np.array([[10.0, 10.0, 50.0, 60.0]], np.float32), (5, 1))
SCORES = np.tile(np.array([[0.2, 0.7, 0.1]], np.float32), (5, 1))


def test_a_model_that_keeps_the_onnx_contract_loads_and_detects(tmp_path: Path):
    detector = Detector(_fake_detector(tmp_path / "fake.onnx", BOXES, SCORES))
    [found] = detector.detect(np.zeros((240, 320, 3), np.uint8), 0.5)
    assert found.label == "ripe" and found.bbox == pytest.approx((10.0, 7.5, 50.0, 45.0))


@pytest.mark.parametrize("mirror", [False, True], ids=["one pass", "passes fused"])
def test_a_box_narrower_than_min_box_px_is_dropped_and_every_other_box_is_kept(tmp_path: Path, mirror: bool):
    boxes = np.array([[10.0, 10.0, 50.0, 60.0], [100.0, 100.0, 108.0, 140.0]], np.float32)  # the second 8 px wide
    scores = np.array([[0.2, 0.7, 0.1], [0.2, 0.1, 0.7]], np.float32)
    detector = Detector(_fake_detector(tmp_path / "fake.onnx", boxes, scores))
    frame = np.zeros((240, 320, 3), np.uint8)
    every = detector.detect(frame, 0.5, mirror=mirror)
    kept = detector.detect(frame, 0.5, mirror=mirror, min_side=10.0)
    assert {d.label for d in every} == {"ripe", "unripe"} and {d.label for d in kept} == {"ripe"}
    assert kept == [d for d in every if min(d.bbox[2] - d.bbox[0], d.bbox[3] - d.bbox[1]) >= 10.0]


@pytest.mark.parametrize(("boxes", "scores", "input_type", "problem"), [
    (BOXES, SCORES[:, :2], onnx.TensorProto.FLOAT, r"output scores has 2 columns, not 3 \(background, ripe, unripe\)"),
    (np.full((5, 4), np.nan, np.float32), SCORES, onnx.TensorProto.FLOAT, "outputs hold NaN or infinite values"),
    (BOXES.ravel(), SCORES.ravel(), onnx.TensorProto.FLOAT, r"output boxes has shape \[20\], not \[A, 4\]"),
    (BOXES, SCORES.ravel(), onnx.TensorProto.FLOAT, r"output scores has shape \[15\], not \[A, 3\]"),
    (BOXES[:3], SCORES, onnx.TensorProto.FLOAT, "outputs boxes and scores have 3 and 5 rows"),
    (BOXES.astype(np.float64), SCORES, onnx.TensorProto.FLOAT, r"outputs are float64 \(boxes\) and float32 \(scores\)"),
    (BOXES, SCORES, onnx.TensorProto.DOUBLE, r"input images is tensor\(double\), not float32"),
    (BOXES, SCORES * 3, onnx.TensorProto.FLOAT, r"not probabilities in \[0, 1\]"),
], ids=["two-classes", "nan-boxes", "1-d-outputs", "1-d-scores", "rows-differ", "float64-outputs", "float64-input",
        "not-probabilities"])
def test_a_model_that_breaks_the_onnx_contract_is_refused_at_load_in_one_line(tmp_path: Path, boxes, scores, input_type,
                                                                               problem: str):
    path = _fake_detector(tmp_path / "broken.onnx", boxes, scores, input_type)
    with pytest.raises(UserError, match=f"^{tmp_path}/broken.onnx: not a renderloop pepper detector \\(.*{problem}") as refused:
        Detector(path)
    assert "\n" not in str(refused.value)


@pytest.mark.parametrize("command", [["run"], ["run", "--online"], ["run", "--mission", "adaptive"], ["eval", "--seeds", "0-1"]])
def test_a_run_whose_config_names_a_broken_model_is_refused_before_any_stage(monkeypatch, capsys, tmp_path: Path,
                                                                            command: list[str]):
    broken = _fake_detector(tmp_path / "broken.onnx", BOXES, SCORES[:, :2])
    (tmp_path / "bad.yaml").write_text(f"detector:\n  model: {broken}\n", encoding="utf-8")
    code, _, err = cli(monkeypatch, capsys, *command, "--preset", "demo", "--config", str(tmp_path / "bad.yaml"),
                       "--out", str(tmp_path / "out"))
    assert code == 2
    assert err.splitlines() == [(f"renderloop: error: {broken}: not a renderloop pepper detector "
                                 "(output scores has 2 columns, not 3 (background, ripe, unripe))")]
    assert not (tmp_path / "out").exists()  # no scene.json, nor the directory it would go in


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
