"""`renderloop train`: the pepper detector on renderloop COCO datasets.

The network starts from its backbone's ImageNet weights (`backbones`), from random
weights (`--backbone mobilenet-v3`) or from an earlier model (`--init`). AdamW with a
linear warm-up and a cosine decay over all epochs; the pretrained layers learn at a
fraction of the rate of the new ones (`backbone_lr_factor`): at the full rate AdamW
wipes out what they learned on ImageNet within a few hundred steps. The first of
them (`frozen_layers`, down to stride 8) do not learn at all; with the network frozen
down to its stride-16 tap, `cached_copies` trains the rest on cached maps of augmented
copies (`feature_cache`) instead of running the whole network every step. After
every epoch a checkpoint (model, optimiser, schedule, history, RNG states) that a
later `renderloop train` with the same settings resumes from, and COCO mAP on the
validation split (pycocotools). At the end the model is exported to ONNX and a
JSON record of the run is written beside it (dataset, epochs, figures).
"""

from __future__ import annotations

import json
import math
import pickle
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from renderloop.config.training import INPUT_SIZES, MOBILENET_V3, PREDATED, SIZE_RULE, TrainSettings
from renderloop.errors import UserError
from renderloop.io.atomic import atomic_path, write_json
from renderloop.perception.detector import CLASSES
from renderloop.perception.training.backbones import frozen_layers
from renderloop.perception.training.data import PepperBoxes, PhotoBoxes, collate
from renderloop.perception.training.feature_cache import FrozenMaps, loss_from_maps
from renderloop.perception.training.from_onnx import freeze_batch_norms, onnx_metadata, weights_from_onnx
from renderloop.perception.training.quantize import QUANTIZED
from renderloop.perception.training.ssd import backbone_of, build_model, export_onnx
from renderloop.perception.training.validate import coco_map

Log = Callable[[str], None]

# NHWC: oneDNN's convolutions train either backbone about 1.5 times as fast on a CPU as in torch's default NCHW
# (benchmarks/train_speed.py). The arithmetic is the same, so a checkpoint of either layout resumes in this one.
MEMORY_FORMAT = torch.channels_last
# A progress line every this many batches: about 80 s at batch 32 on a 2-core CPU (8 images a second), so a 10-minute
# epoch shows it is alive; a GPU's epoch of a few thousand images prints a handful.
PROGRESS_BATCHES = 20


def _device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise UserError("--device cuda: no CUDA GPU is available")
    return torch.device(name)


def _schedule(settings: TrainSettings, steps_per_epoch: int) -> Callable[[int], float]:
    total = max(1, settings.epochs * steps_per_epoch)

    def factor(step: int) -> float:
        if step < settings.warmup_steps:
            return (step + 1) / settings.warmup_steps
        progress = (step - settings.warmup_steps) / max(1, total - settings.warmup_steps)
        return 0.5 * (1.0 + math.cos(math.pi * min(progress, 1.0)))

    return factor


def _save_checkpoint(path: Path, state: dict) -> None:
    with atomic_path(path) as tmp:
        torch.save(state, tmp)


def _batches(loader: torch.utils.data.DataLoader) -> Iterator:
    """The loader's batches; a bad image found in a loading worker comes back with the worker's traceback in its
    message, so only its last line (ours) is kept."""
    try:
        yield from loader
    except UserError as error:
        last = str(error).strip().splitlines()[-1]
        raise UserError(last.removeprefix(f"{UserError.__module__}.{UserError.__name__}: ")) from None


def _load_checkpoint(path: Path, device: torch.device) -> dict:
    """The checkpoint an earlier run left at this --out; a file there that is not one is not ours to resume or replace."""
    try:
        state = torch.load(path, map_location=device, weights_only=True)  # tensors and plain data: nothing runs
    except (OSError, RuntimeError, TypeError, EOFError, pickle.UnpicklingError) as error:
        raise UserError(f"{path}: not a renderloop training checkpoint ({type(error).__name__}); give another --out") from None
    if not isinstance(state, dict) or not {"model", "optimizer", "record", "epoch"} <= state.keys():
        raise UserError(f"{path}: not a renderloop training checkpoint; give another --out")
    return state


def _differences(recorded: dict, given: dict, recorded_images: int, images: int) -> str:
    """What a checkpoint trained with and this run would not, as its options say it: '--backbone efficientnet-lite0
    (this run: efficientnet-lite0-s8)'; a run resumes only what it started (a default may have changed since)."""
    names = [name for name in {**recorded, **given} if recorded.get(name) != given.get(name)]
    differ = [f"--{name.replace('_', '-')} {recorded.get(name)} (this run: {given.get(name)})" for name in names]
    if recorded_images != images:
        differ.append(f"{recorded_images} training images (this run: {images})")
    return ", ".join(differ)


def _parameter_groups(model: torch.nn.Module, settings: TrainSettings) -> list[dict]:
    """The pretrained backbone at its fraction of the learning rate, the rest at the full rate; a network from random
    weights learns at the full rate throughout, and frozen layers not at all."""
    if settings.backbone == MOBILENET_V3:
        return [{"params": list(model.parameters())}]
    pretrained = {id(p) for p in model.backbone.features.parameters()}
    learning = [p for p in model.parameters() if p.requires_grad]  # the frozen layers are nobody's
    backbone = [p for p in learning if id(p) in pretrained]
    rest = [p for p in learning if id(p) not in pretrained]
    return [{"params": backbone, "lr": settings.learning_rate * settings.backbone_lr_factor}, {"params": rest}]


def _initial_weights(path: Path, model: torch.nn.Module, backbone: str) -> dict:
    """The model weights of an earlier run's checkpoint, or of a renderloop ONNX detector (the shipped one, say):
    fine-tuning on a grown or new dataset starts there."""
    if path.suffix == ".onnx":
        metadata = onnx_metadata(path)
        if QUANTIZED in metadata:
            raise UserError(f"--init {path}: quantized ({metadata[QUANTIZED]}), its float weights are gone; "
                            "fine-tune the float model it was made from")
        built_on = backbone_of(metadata.get("renderloop_detector", ""))
        if built_on is not None and built_on != backbone:
            raise UserError(f"--init {path}: a detector on {built_on}; train it with --backbone {built_on}")
        return weights_from_onnx(path, model)
    try:
        return torch.load(path, map_location="cpu", weights_only=True)["model"]
    except (OSError, RuntimeError, KeyError, TypeError, EOFError, pickle.UnpicklingError) as error:
        raise UserError(f"--init {path}: not a renderloop training checkpoint ({type(error).__name__})") from None


def backbone_of_init(path: Path) -> str:
    """The backbone the weights at `path` were trained on: an ONNX detector's metadata says it; a checkpoint's record
    does (a record without one is of the random-weights MobileNetV3, the only backbone before there was a choice)."""
    path = Path(path)
    if path.suffix == ".onnx":
        name = onnx_metadata(path).get("renderloop_detector", "")
        built_on = backbone_of(name)
        if built_on is None:
            raise UserError(f"--init {path}: not a renderloop detector (its metadata names {name!r}); give --backbone")
        return built_on
    try:
        record = torch.load(path, map_location="cpu", weights_only=True)["record"]
    except (OSError, RuntimeError, KeyError, TypeError, EOFError, pickle.UnpicklingError) as error:
        raise UserError(f"--init {path}: not a renderloop training checkpoint ({type(error).__name__})") from None
    return record.get("settings", {}).get("backbone", PREDATED["backbone"])


@dataclass(frozen=True)
class Photos:
    """A user's labelled photos to train on besides (or instead of) renders: the folder, its COCO file, and the class
    of boxes whose category names no ripeness (None: every category must name one)."""

    folder: Path
    coco: Path
    fallback_class: str | None = None


def train_detector(datasets: Path | list[Path], out: Path, settings: TrainSettings, device: str = "auto", workers: int = 1,
                   log: Log = print, init: Path | None = None, photos: Photos | None = None,
                   input_size: int | None = None) -> dict:
    """Train on the train splits of one or more datasets together, and on `photos` if given; each dataset's val split
    is scored apart (figures of sets of different difficulty would not mean anything mixed), the first's as the
    headline figures. Photos have no validation split: score the model on photos it did not train on with
    `renderloop score-photos`. The network trains at `settings.train_size` and is exported for an `input_size`
    square input (None: the size it trained at); a finished run given another size exports its model again."""
    datasets, out = [Path(d) for d in (datasets if isinstance(datasets, list) else [datasets])], Path(out)
    if not datasets and photos is None:
        raise UserError("give a dataset folder made by `renderloop dataset`, or --photos with --coco, to train on")
    if out.suffix != ".onnx":
        raise UserError(f"--out {out}: the model file must end in .onnx")
    input_size = settings.train_size if input_size is None else input_size
    if input_size not in INPUT_SIZES:
        raise UserError(f"--input-size {input_size}: give {SIZE_RULE}")
    checkpoint_path = out.with_suffix(".ckpt")
    if not checkpoint_path.is_file():  # a resumed run's files are its own; without a checkpoint, nothing here is ours
        for path in (out, out.with_suffix(".json")):
            if path.exists():
                raise UserError(f"--out {out}: {path} exists and no training checkpoint beside it; give another --out")
    out.parent.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(settings.seed)
    parts = [PepperBoxes(dataset, "train", augment=True) for dataset in datasets]
    if photos is not None:
        parts.append(PhotoBoxes(photos.folder, photos.coco, photos.fallback_class, augment=True))
    val_sets = [PepperBoxes(dataset, "val", augment=False) for dataset in datasets]
    for part in parts:
        if len(part) == 0:
            raise UserError(f"{part.annotation_file}: no training images")
    train_set = torch.utils.data.ConcatDataset(parts)
    run_device = _device(device)
    loader = torch.utils.data.DataLoader(
        train_set, batch_size=settings.batch_size, shuffle=True, drop_last=len(train_set) > settings.batch_size,
        collate_fn=collate, num_workers=workers, persistent_workers=workers > 0,
        generator=torch.Generator().manual_seed(settings.seed),
    )
    model = build_model(settings.backbone, pretrained=init is None, train_size=settings.train_size,
                        match_iou=settings.match_iou)
    frozen_norms = init is not None and Path(init).suffix == ".onnx"  # its batch norms are folded: keep them as they are
    if init is not None:
        model.load_state_dict(_initial_weights(Path(init), model, settings.backbone))
    frozen = frozen_layers(model, settings.frozen_layers)
    model = model.to(run_device, memory_format=MEMORY_FORMAT)
    cache = None
    if settings.cached_copies:  # built before a resumed run's state is restored: its own draws, the same maps again
        cache = FrozenMaps(model, train_set, settings.cached_copies, settings.seed, run_device, workers, MEMORY_FORMAT)
        log(f"cached the maps of {len(cache.targets)} copies of {len(train_set)} images ({cache.gib:.1f} GiB)")
    optimizer = torch.optim.AdamW(_parameter_groups(model, settings), lr=settings.learning_rate, weight_decay=settings.weight_decay)
    scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, _schedule(settings, len(loader)))
    schedule = settings.model_dump(exclude={"max_steps"})  # what a resumed run must share
    record = {"settings": schedule, "init": str(init) if init else None, "frozen_batch_norms": frozen_norms, "datasets": [str(d) for d in datasets],
              "photos": {key: str(value) for key, value in asdict(photos).items()} if photos else None,
              "train_images": len(train_set), "val_images": [len(v) for v in val_sets], "classes": list(CLASSES), "history": []}
    start_epoch = 0
    if checkpoint_path.is_file():
        state = _load_checkpoint(checkpoint_path, run_device)
        # a checkpoint written before a setting existed trained with its default then
        recorded = {**TrainSettings().model_dump(exclude={"max_steps"}), **PREDATED, **state["record"]["settings"]}
        if recorded != record["settings"] or state["record"]["train_images"] != len(train_set):
            differ = _differences(recorded, record["settings"], state["record"]["train_images"], len(train_set))
            raise UserError(f"{checkpoint_path}: a checkpoint of other settings or data ({differ}); give the same to "
                            "resume it, or delete it to start over")
        model.load_state_dict(state["model"])
        optimizer.load_state_dict(state["optimizer"])
        scheduler.load_state_dict(state["scheduler"])
        torch.set_rng_state(state["torch_rng"])
        loader.generator.set_state(state["loader_rng"])
        record, start_epoch = state["record"], state["epoch"]
        log(f"resuming after epoch {start_epoch} from {checkpoint_path}")

    steps = start_epoch * len(loader)
    for epoch in range(start_epoch, settings.epochs):
        model.train()
        for layer in frozen:
            layer.eval()
        if frozen_norms:
            freeze_batch_norms(model)
        began, seen, losses = time.perf_counter(), 0, []
        if cache is None:
            batches = _batches(loader)
        else:  # the same number of batches an epoch as the loader's, in an order drawn from its generator
            order = torch.randperm(len(train_set), generator=loader.generator)
            batches = cache.epoch(epoch, order, settings.batch_size, loader.drop_last)
        for images, targets in batches:
            targets = [{"boxes": t["boxes"].to(run_device), "labels": t["labels"].to(run_device)} for t in targets]
            if cache is None:
                loss = sum(model([image.to(run_device) for image in images], targets).values())
            else:
                maps = [m.to(run_device, memory_format=MEMORY_FORMAT) for m in images]
                loss = sum(loss_from_maps(model, maps, targets, cache.input_size).values())
            if not torch.isfinite(loss):
                raise RuntimeError(f"training diverged at epoch {epoch + 1} (loss {float(loss)})")
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            scheduler.step()
            losses.append(loss.item())
            seen += len(targets)
            steps += 1
            if len(losses) % PROGRESS_BATCHES == 0:
                log(f"epoch {epoch + 1}: {len(losses)} of {len(loader)} batches, loss {np.mean(losses[-PROGRESS_BATCHES:]):.3f}, "
                    f"{seen / (time.perf_counter() - began):.1f} images/s")
            if settings.max_steps is not None and steps >= settings.max_steps:
                break
        seconds = time.perf_counter() - began
        scores = [coco_map(model, val_set, run_device) if len(val_set) else {} for val_set in val_sets]
        entry = {"epoch": epoch + 1, "loss": float(np.mean(losses)), "images_per_s": seen / seconds, **(scores[0] if scores else {})}
        if len(datasets) > 1:
            entry["val"] = {str(dataset): figures for dataset, figures in zip(datasets, scores)}
        record["history"].append(entry)
        log(json.dumps(entry))
        _save_checkpoint(checkpoint_path, {
            "model": model.state_dict(), "optimizer": optimizer.state_dict(), "scheduler": scheduler.state_dict(),
            "torch_rng": torch.get_rng_state(), "loader_rng": loader.generator.get_state(), "record": record, "epoch": epoch + 1,
        })
        if settings.max_steps is not None and steps >= settings.max_steps:
            break

    model.cpu().eval()
    final = record["history"][-1] if record["history"] else {}
    record["input_size"] = input_size
    export_onnx(model, out, {"epochs": str(len(record["history"])), "val_map50": str(final.get("map50", "n/a"))}, input_size)
    write_json(out.with_suffix(".json"), record)
    return record
