"""Training on cached maps: the same losses as the whole network, the same maps on resuming, refused where
the layers before the tap still learn."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from conftest import cli
from renderloop.config.training import CACHE_FROM
from renderloop.perception.training.backbones import STRIDE_16_BLOCK, frozen_layers
from renderloop.perception.training.data import PepperBoxes, collate
from renderloop.perception.training.feature_cache import FrozenMaps, loss_from_maps, frozen_maps
from renderloop.perception.training.ssd import build_model
from renderloop.perception.training.train import MEMORY_FORMAT, TrainSettings, train_detector


def test_the_cache_starts_where_the_frozen_part_of_the_network_ends():
    assert CACHE_FROM == STRIDE_16_BLOCK + 1  # the config's bound, which cannot import torch, is the network's


@pytest.mark.parametrize("backbone", ["efficientnet-lite0", "efficientnet-lite0-s8"])
def test_the_loss_from_cached_maps_is_the_loss_of_the_whole_network(tiny_dataset: Path, backbone: str):
    torch.manual_seed(0)
    model = build_model(backbone, pretrained=False)
    frozen = frozen_layers(model, CACHE_FROM)
    model = model.to(memory_format=MEMORY_FORMAT).train()
    for layer in frozen:
        layer.eval()
    images, targets = collate([PepperBoxes(tiny_dataset, "train", augment=False)[i] for i in range(4)])
    targets = [{"boxes": t["boxes"], "labels": t["labels"]} for t in targets]
    whole = model(images, targets)
    maps, resized, input_size = frozen_maps(model, images, targets, MEMORY_FORMAT)
    assert input_size == (320, 320)
    # the stride-16 map, and before a stride-8 tap the 40-channel map it is made from
    assert [tuple(m.shape[1:]) for m in maps] == ([(40, 40, 40)] if backbone.endswith("s8") else []) + [(672, 20, 20)]
    cached = loss_from_maps(model, maps, resized, input_size)
    assert whole.keys() == cached.keys()
    for name in whole:
        assert cached[name].item() == pytest.approx(whole[name].item(), rel=1e-4), name
    # and it learns: the loss carries gradients to the layers after the tap, none to those before
    sum(cached.values()).backward()
    assert model.head.classification_head.module_list[0][1].weight.grad is not None
    assert all(p.grad is None for p in model.backbone.features[:-1].parameters())


def test_each_epoch_draws_one_copy_of_every_image_and_the_same_seed_draws_the_same_copies(tiny_dataset: Path):
    model = build_model("efficientnet-lite0")  # ImageNet's layers: random ones fade to zeros by stride 16
    frozen_layers(model, CACHE_FROM)
    train = PepperBoxes(tiny_dataset, "train", augment=True)
    cache = FrozenMaps(model, train, copies=2, seed=5, device=torch.device("cpu"), workers=0,
                              memory_format=MEMORY_FORMAT)
    again = FrozenMaps(model, train, copies=2, seed=5, device=torch.device("cpu"), workers=0,
                              memory_format=MEMORY_FORMAT)
    [maps] = cache.maps
    assert maps.shape == (16, 672, 20, 20) and maps.dtype == torch.float16
    assert torch.equal(maps, again.maps[0])
    assert not torch.equal(maps[:8], maps[8:])  # two augmentation draws of each image
    order = torch.arange(8)
    for epoch in (0, 1, 2):
        batches = list(cache.epoch(epoch, order, batch_size=3, drop_last=True))
        assert [len(targets) for _, targets in batches] == [3, 3]  # as the loader's drop_last
        first_copy = (epoch % 2) * 8
        assert torch.equal(batches[0][0][0], maps[first_copy:first_copy + 3].float())


def test_a_cached_run_resumed_after_its_first_epoch_ends_as_an_unbroken_one(tiny_dataset: Path, tmp_path: Path):
    settings = TrainSettings(epochs=2, batch_size=4, warmup_steps=1, frozen_layers=CACHE_FROM, cached_copies=2)
    whole = train_detector(tiny_dataset, tmp_path / "whole.onnx", settings, device="cpu", workers=0, log=lambda _: None)
    first = TrainSettings(**{**settings.model_dump(), "max_steps": 2})  # two steps: the first epoch
    train_detector(tiny_dataset, tmp_path / "broken.onnx", first, device="cpu", workers=0, log=lambda _: None)
    logged = []
    resumed = train_detector(tiny_dataset, tmp_path / "broken.onnx", settings, device="cpu", workers=0, log=logged.append)
    assert any(line.startswith("resuming after epoch 1") for line in logged)
    assert [e["loss"] for e in resumed["history"]] == pytest.approx([e["loss"] for e in whole["history"]], rel=1e-5)
    a = torch.load(tmp_path / "whole.ckpt", weights_only=True)["model"]
    b = torch.load(tmp_path / "broken.ckpt", weights_only=True)["model"]
    assert all(torch.allclose(a[key].float(), b[key].float(), atol=1e-6) for key in a)


def test_a_cache_before_the_layers_it_holds_are_frozen_is_refused_in_one_line(tiny_dataset: Path, tmp_path: Path,
                                                                              monkeypatch, capsys):
    out = tmp_path / "m.onnx"
    code, _, err = cli(monkeypatch, capsys, "train", str(tiny_dataset), "--out", str(out), "--cached-copies", "4",
                       "--frozen-layers", "6")
    assert code != 0 and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert ("cached_copies needs an efficientnet-lite0 or efficientnet-lite0-s8 backbone with frozen_layers of at "
            f"least {CACHE_FROM}") in err
    assert not out.exists() and not out.with_suffix(".ckpt").exists()


def test_a_checkpoint_from_before_the_cache_existed_resumes_as_a_run_without_one(tiny_dataset: Path, tmp_path: Path):
    out = tmp_path / "old.onnx"
    settings = TrainSettings(epochs=2, batch_size=4, warmup_steps=1, backbone="mobilenet-v3")
    train_detector(tiny_dataset, out, TrainSettings(**{**settings.model_dump(), "max_steps": 2}), device="cpu", workers=0,
                   log=lambda _: None)
    state = torch.load(out.with_suffix(".ckpt"), weights_only=True)
    del state["record"]["settings"]["cached_copies"]  # as a checkpoint written before the setting was
    torch.save(state, out.with_suffix(".ckpt"))
    logged = []
    record = train_detector(tiny_dataset, out, settings, device="cpu", workers=0, log=logged.append)
    assert logged[0].startswith("resuming after epoch 1") and [e["epoch"] for e in record["history"]] == [1, 2]
