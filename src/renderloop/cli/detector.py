"""The detector's verbs: training sets, training, quantizing, the threshold and the score on labelled photos."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from renderloop.cli.common import (MODEL_HELP, SHIPPED_NAME, THRESHOLD_HELP, Address, Choice, Enlargement, Executor, Force, MinBox,
                                   Mirror, Windows, Workers, app, detector_options, named_model, photo_detector,
                                   progress_bar, split_names, train_extra)
from renderloop.config.dataset import DatasetSpec
from renderloop.config.fields import checked
from renderloop.config.training import BACKBONES, DEFAULT_BACKBONE, TrainSettings
from renderloop.config.training import DEVICES as TRAIN_DEVICES
from renderloop.errors import UserError
from renderloop.perception.detector import CLASSES

PANEL = "Detector"  # where help lists these verbs, after a run's


def _spec_option(name: str, flag: str | None = None) -> Any:
    """The `dataset` option of a DatasetSpec field: the model's description and default; a value not given (None) is
    the model's default, and the model checks the range of one given."""
    field = DatasetSpec.model_fields[name]
    default = ",".join(field.default) if name in ("styles", "environments") else field.default
    return typer.Option(*((flag,) if flag else ()), help=f"{field.description} Default: {default}.", show_default=False)


@app.command(rich_help_panel=PANEL)
def dataset(
    out: Annotated[Path, typer.Option(help="Dataset folder (images/, labels/, annotations/).")],
    images: Annotated[int, typer.Option(min=1, max=10_000_000, help="Images in the dataset; more than it has adds to it.")],
    seed: Annotated[int | None, _spec_option("seed")] = None,
    views_per_scene: Annotated[int | None, _spec_option("views_per_scene")] = None,
    width: Annotated[int | None, _spec_option("width")] = None,
    distance: Annotated[tuple[float, float] | None, _spec_option("distance")] = None,
    sensor: Annotated[float | None, _spec_option("sensor")] = None,
    styles: Annotated[str | None, _spec_option("styles")] = None,
    environments: Annotated[str | None, _spec_option("environments")] = None,
    clutter: Annotated[bool | None, _spec_option("clutter", "--clutter/--no-clutter")] = None,
    close: Annotated[float | None, _spec_option("close")] = None,
    picked: Annotated[float | None, _spec_option("picked")] = None,
    workers: Workers = 1,
    executor: Executor = "local",
    address: Address = None,
    force: Force = False,
) -> None:
    """Render a COCO detection dataset (ripe, unripe) of random greenhouse views with Cycles, boxes from the masks."""
    from renderloop.dataset.build import build_dataset
    from renderloop.parallel import Executor as Parallel

    given = {"seed": seed, "views_per_scene": views_per_scene, "width": width, "height": None if width is None else width * 3 // 4,
             "distance": distance, "sensor": sensor, "styles": None if styles is None else split_names(styles),
             "environments": None if environments is None else split_names(environments), "clutter": clutter, "close": close,
             "picked": picked}
    spec = DatasetSpec.of(**{name: value for name, value in given.items() if value is not None})
    with progress_bar("dataset") as progress:
        made = build_dataset(out, images, spec, Parallel.of(executor, workers, address), force, progress)
    typer.echo(f"dataset: rendered {made} images, {images} in {out}")


@app.command("dataset-from-runs", rich_help_panel=PANEL)
def dataset_runs(
    run_dirs: Annotated[list[Path], typer.Argument(help="Rendered run directories (with masks); the last --val-runs validate.",
                                                   show_default=False)],
    out: Annotated[Path, typer.Option(help="Dataset folder to (re)write: images/, labels/, annotations/.")],
    every: Annotated[int, typer.Option(min=1, max=1_000_000, help="Take every N-th frame of each run.")] = 1,
    val_runs: Annotated[int, typer.Option(min=0, help="How many of the last runs form the validation split.")] = 1,
) -> None:
    """A COCO detection dataset of the frames scan runs flew, boxes from their masks: fine-tuning data in the flight's own views."""
    from renderloop.dataset.from_runs import dataset_from_runs

    with progress_bar("dataset") as progress:
        made = dataset_from_runs(run_dirs, out, every, val_runs, progress)
    typer.echo(f"dataset: {made} frames of {len(run_dirs)} runs in {out}")

def _setting(name: str) -> Any:
    """The `train` option of a TrainSettings field: the model's description and default; a value not given (None) is
    the model's default, and the model checks the range of one given."""
    field = TrainSettings.model_fields[name]
    return typer.Option(help=f"{field.description} Default: {field.default}.", show_default=False)


@app.command(rich_help_panel=PANEL)
def train(
    out: Annotated[Path, typer.Option(help="ONNX model to write; its checkpoint is OUT with .ckpt.")],
    dataset_dirs: Annotated[list[Path] | None, typer.Argument(help="Dataset folders made by `renderloop dataset`; several "
                                                              "train together.", show_default=False)] = None,
    epochs: Annotated[int | None, _setting("epochs")] = None,
    batch_size: Annotated[int | None, _setting("batch_size")] = None,
    learning_rate: Annotated[float | None, _setting("learning_rate")] = None,
    warmup_steps: Annotated[int | None, _setting("warmup_steps")] = None,
    seed: Annotated[int | None, _setting("seed")] = None,
    frozen_layers: Annotated[int | None, _setting("frozen_layers")] = None,
    cached_copies: Annotated[int | None, _setting("cached_copies")] = None,
    device: Annotated[str, Choice(TRAIN_DEVICES, "Where to train; auto: cuda when there is one.")] = "auto",
    loader_workers: Annotated[int, typer.Option(min=0, max=64, help="Data-loading processes.")] = 1,
    init: Annotated[Path | None, typer.Option(help="Start from these weights (fine-tuning): an earlier run's .ckpt, a "
                                              f"renderloop ONNX detector, or '{SHIPPED_NAME}' for the model in the package.")] = None,
    backbone: Annotated[str | None, Choice(BACKBONES, f"{TrainSettings.model_fields['backbone'].description} Default: "
                                           f"--init's, else {DEFAULT_BACKBONE}.")] = None,
    photos: Annotated[Path | None, typer.Option(help="Your own labelled photos to train on too (a folder; with --coco): "
                                                "renders first, then a fine-tune with these, --init the model.")] = None,
    coco: Annotated[Path | None, typer.Option(help="With --photos: their COCO labels, as `score-photos` reads them.")] = None,
    photo_class: Annotated[str | None, Choice(CLASSES, "With --photos: the class of boxes whose category names no "
                                              "ripeness (a one-class set).")] = None,
    train_size: Annotated[int | None, _setting("train_size")] = None,
    match_iou: Annotated[float | None, _setting("match_iou")] = None,
    input_size: Annotated[int | None, typer.Option(help="Square input of the exported model, px (a multiple of 32); "
                                                   "default the size it trains at. Given to a finished run, exports "
                                                   "its model again.")] = None,
) -> None:
    """Train the pepper detector (SSDlite) from ImageNet or --init weights; resumes from its checkpoint; exports ONNX."""
    try:
        from renderloop.perception.training.train import Photos, backbone_of_init, train_detector
    except ImportError as error:
        raise train_extra("training", error) from None
    init = named_model(init)
    if (photos is None) != (coco is None):
        raise UserError("--photos and --coco go together: the photo folder and its COCO labels")
    if backbone is None and init is not None:
        backbone = backbone_of_init(init)
    given = {"epochs": epochs, "batch_size": batch_size, "learning_rate": learning_rate, "warmup_steps": warmup_steps,
             "seed": seed, "backbone": backbone, "frozen_layers": frozen_layers,
             "cached_copies": cached_copies, "train_size": train_size, "match_iou": match_iou}
    settings = checked(TrainSettings, "train", **{name: value for name, value in given.items() if value is not None})
    own = Photos(photos, coco, photo_class) if photos is not None else None
    record = train_detector(dataset_dirs or [], out, settings, device, loader_workers, log=lambda line: typer.echo(line, err=True),
                            init=init, photos=own, input_size=input_size)
    last = record["history"][-1] if record["history"] else {}
    typer.echo(f"train: wrote {out} (val mAP@0.5 {last.get('map50', float('nan')):.3f})")


@app.command(rich_help_panel=PANEL)
def quantize(
    model: Annotated[Path, typer.Argument(help=f"The ONNX detector to quantize, or '{SHIPPED_NAME}'.", show_default=False)],
    dataset_dirs: Annotated[list[Path], typer.Argument(help="Dataset folders made by `renderloop dataset`: the "
                                                       "calibration renders come from their training splits.",
                                                       show_default=False)],
    out: Annotated[Path, typer.Option(help="The int8 ONNX model to write.", show_default=False)],
    images: Annotated[int, typer.Option(min=1, max=100_000, help="Calibration renders.")] = 64,
    seed: Annotated[int, typer.Option(help="Seed of the calibration renders' draw.")] = 0,
    force: Annotated[bool, typer.Option("--force", help="Replace --out if it exists.")] = False,
) -> None:
    """Quantize a detector to int8 for ONNX Runtime's integer kernels, calibrated on renders (docs/stages/perception.md)."""
    try:
        from renderloop.perception.training.quantize import quantize_on_renders
    except ImportError as error:
        raise train_extra("quantizing", error) from None
    made = quantize_on_renders(named_model(model), dataset_dirs, out, images, seed, force)
    typer.echo(f"quantize: wrote {made}")


@app.command(rich_help_panel=PANEL)
def blend(
    first: Annotated[Path, typer.Argument(help=f"The ONNX detector trained on from, or '{SHIPPED_NAME}'.", show_default=False)],
    second: Annotated[Path, typer.Argument(help="The ONNX detector trained on from FIRST (`train --init FIRST`, or on "
                                           "from such a model).", show_default=False)],
    out: Annotated[Path, typer.Option(help="The blended ONNX model to write.", show_default=False)],
    share: Annotated[float, typer.Option(min=0.0, max=1.0, help="SECOND's share of each weight; FIRST has the rest.")] = 0.5,
    force: Annotated[bool, typer.Option("--force", help="Replace --out if it exists.")] = False,
) -> None:
    """Blend two detectors of one network weight by weight (WiSE-FT): a fine-tune's gains with what it forgot (docs/stages/perception.md)."""
    try:
        from renderloop.perception.training.blend import blend_detectors
    except ImportError as error:
        raise train_extra("blending", error) from None
    typer.echo(f"blend: wrote {blend_detectors(named_model(first), named_model(second), share, out, force)}")

@app.command(name="threshold", rich_help_panel=PANEL)
def choose_threshold(
    run_dirs: Annotated[list[Path], typer.Argument(help="Rendered runs the detector never trained on.", show_default=False)],
    model: Annotated[Path | None, typer.Option(help=MODEL_HELP + " Default: the shipped one.")] = None,
    windows: Windows = None,
    mirror: Mirror = None,
    min_box: MinBox = None,
    enlargement: Enlargement = None,
    max_false: Annotated[float, typer.Option(min=0.0, max=1.0, help="Share of false detections allowed.")] = 0.05,
) -> None:
    """Choose the detector's score threshold on rendered runs: the lowest with at most --max-false of its detections false."""
    from renderloop.perception.detector import Detector
    from renderloop.perception.threshold import choose, format_scores, score_thresholds, search_run, threshold_text

    settings = photo_detector(detector_options(model, None, windows, mirror, min_box, enlargement))
    detector = Detector(settings.model)
    with progress_bar("threshold") as progress:
        runs = [search_run(run_dir, detector, settings, progress) for run_dir in run_dirs]
    scores = score_thresholds(runs)
    chosen = choose(scores, max_false)
    typer.echo(format_scores(scores, chosen))
    if chosen is None:
        raise UserError(f"no threshold up to {threshold_text(scores[-1].threshold)} keeps false detections at or under {max_false:.1%}")
    text = threshold_text(chosen.threshold)
    typer.echo(f"threshold: {text} (recall {chosen.recall:.3f}, {chosen.false_rate:.1%} false); "
               f"set detector.score_threshold or pass renderloop detect --threshold {text}")

@app.command(name="score-photos", rich_help_panel=PANEL)
def score_photo_folder(
    folder: Annotated[Path, typer.Argument(help="Folder of the labelled photos (PNG/JPEG).", show_default=False)],
    coco: Annotated[Path, typer.Option(help="COCO labels of the photos: images, annotations (bbox: x, y, width, height in pixels), "
                                       "categories (ripe/unripe or red/yellow/orange/green give per-class scores too).",
                                       show_default=False)],
    out: Annotated[Path, typer.Option(help="Folder to write score.json, pr_curve.png and sheet.png into.", show_default=False)],
    model: Annotated[Path | None, typer.Option(help=MODEL_HELP + " Default: the shipped one.")] = None,
    threshold: Annotated[float | None, typer.Option(min=0.0, max=1.0, help=THRESHOLD_HELP)] = None,
    windows: Windows = None,
    mirror: Mirror = None,
    min_box: MinBox = None,
    enlargement: Enlargement = None,
    force: Annotated[bool, typer.Option("--force", help="Replace a score that exists in --out.")] = False,
) -> None:
    """Score the detector on your labelled photos: recall, precision, F1, AP@0.5 (pycocotools) and the curve over thresholds."""
    from renderloop.perception.photo_score import OUTPUTS as PHOTO_SCORE_FILES
    from renderloop.perception.photo_score import score_photos, summary

    settings = photo_detector(detector_options(model, threshold, windows, mirror, min_box, enlargement))
    with progress_bar("score-photos") as progress:
        record = score_photos(folder, coco, out, settings, force, progress)
    for line in summary(record):
        typer.echo(f"score-photos: {line}")
    typer.echo(f"score-photos: wrote {out} ({', '.join(sorted(PHOTO_SCORE_FILES))})")
