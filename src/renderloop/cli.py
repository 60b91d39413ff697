"""The `renderloop` command: one verb per pipeline stage, plus `run` for all of them.

Bad input ends in one line on stderr and exit code 2 (UserError); an operating-system
failure such as a full disk or a read-only directory in one line and exit code 1.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from typer.exceptions import Abort as TyperAbort
from typer.core import TyperCommand, TyperGroup
from typer.exceptions import TyperException

from renderloop import __version__
from renderloop import parallel
from renderloop.config import PRESETS, Config, DetectorConfig, MissionConfig, RendererConfig, choices, config_schema, load_config
from renderloop.config.fields import checked
from renderloop.config.training import BACKBONES, DEFAULT_BACKBONE, TrainSettings
from renderloop.config.training import DEVICES as TRAIN_DEVICES
from renderloop.config.dataset import DatasetSpec
from renderloop.errors import UserError, did_you_mean
from renderloop.io.atomic import final_path
from renderloop.perception.detector import CLASSES

# Each command imports the stages it runs inside its own body: `renderloop fly` has no use for the detector,
# scikit-learn or Ray, and importing them would be a large part of its time.

def _choice_metavar(values: Sequence[str], several: bool = False) -> str:
    """How help shows an option of a fixed set of values: [raster|cycles], or [static|adaptive],... for a list."""
    return f"[{'|'.join(values)}]" + (",..." if several else "")


def _readable(param: Any) -> None:
    """A parameter as help and usage lines show it: a flag takes no value and shows none (not `<bool>`), an argument
    shows its name in capitals (RUN_DIR); an option's type (`<path>`, or its choices, see `Choice`) stays."""
    if getattr(param, "is_flag", False):
        param.metavar = ""
    elif param.param_type_name == "argument" and param.metavar is None:
        param.metavar = param.name.upper() + ("..." if param.nargs != 1 else "")


class _Readable:
    """A command whose parameters read as the command is typed (see `_readable`)."""

    def get_params(self, ctx: Any) -> list:
        params = super().get_params(ctx)  # type: ignore[misc]  # the --help option joins here
        for param in params:
            _readable(param)
        return params


class _Command(_Readable, TyperCommand):
    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        """`[OPTIONS] RUN_DIR`, an optional argument in brackets: click's own braces read as a literal `{run_dir}`."""
        pieces = [self.options_metavar] if self.options_metavar else []
        for param in self.get_params(ctx):
            if param.param_type_name == "argument":
                pieces.append(param.metavar if param.required else f"[{param.metavar}]")
        return pieces


class _Group(_Readable, TyperGroup):
    """The root command, whose --version and --help are flags too."""


class _Typer(typer.Typer):
    """Every verb is a `_Command` unless it names its own class."""

    def command(self, *args: Any, cls: type[TyperCommand] | None = None, **kwargs: Any) -> Callable:
        return super().command(*args, cls=cls or _Command, **kwargs)


def Choice(values: Sequence[str], help: str, *decls: str, several: bool = False, check: bool = True, **kwargs: Any) -> Any:
    """An option of one of `values` (comma-separated values with `several`): its help shows them, and a value not among
    them is refused before the verb starts, naming the option, the values and the closest one: `--mission adaptiv:
    choose from static, adaptive; did you mean adaptive?`. `check=False` leaves the refusal to the code that reads it."""
    def refuse_unknown(ctx: Any, param: Any, value: str | None) -> str | None:
        if value is None or not check or ctx.resilient_parsing:
            return value
        for name in _names(value) if several else (value,):
            if name not in values:
                raise UserError(f"{param.opts[0]} {value}: choose from {', '.join(values)}{did_you_mean(name, values)}")
        return value

    return typer.Option(*decls, help=help, metavar=_choice_metavar(values, several), callback=refuse_unknown, **kwargs)


app = _Typer(
    cls=_Group,
    name="renderloop",
    help="Render-in-the-loop aerial robotics simulator: sweet-pepper yield estimation in a greenhouse.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

# load_config refuses an unknown preset itself, with the sentence the Python API gives
Preset = Annotated[str, Choice(PRESETS, "Config preset; --config's fields go over it.", check=False)]
ConfigFile = Annotated[Path | None, typer.Option("--config", help="YAML file whose fields override the preset.")]
Seed = Annotated[int | None, typer.Option(help="Seed of every random choice (overrides the config's).")]
Out = Annotated[Path, typer.Option(help="Run directory to write into.")]
Force = Annotated[bool, typer.Option("--force", help="Redo stages whose outputs already exist.")]
MISSIONS = choices(MissionConfig, "kind")
MissionKind = Annotated[str | None, Choice(
    MISSIONS, "static: the planned scan; adaptive: a coarse pass, then re-scans where the count is uncertain (mission.kind).",
    "--mission")]
RunDir = Annotated[Path, typer.Argument(help="Run directory made by `renderloop scene`.", show_default=False)]
Windows = Annotated[str | None, typer.Option(help="Also search the windows of these columns x rows layouts of each image, "
                                             "e.g. 2x2,3x2; none: whole images only; default: the config's (2x2,3x2).")]
Mirror = Annotated[bool | None, typer.Option("--mirror/--no-mirror", help="Also search each image mirrored; default: the config's.",
                                             show_default=False)]
MinBox = Annotated[float | None, typer.Option("--min-box", min=0.0, help="Shorter side in px a detection's box needs; "
                                              "default: the config's (0: every box).")]


def _version(value: bool) -> None:
    if value:
        typer.echo(f"renderloop {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version.")] = False,
) -> None:
    """Render-in-the-loop aerial robotics simulator: sweet-pepper yield estimation in a greenhouse."""


@app.command()
def scene(out: Out, preset: Preset = "demo", config: ConfigFile = None, seed: Seed = None, force: Force = False) -> None:
    """Generate the greenhouse: config.yaml, scene.json, world.xml (MJCF) and a top-view PNG."""
    from renderloop.scene.stage import run_scene

    resolved = load_config(preset, config, seed)
    made = run_scene(out, resolved, force)
    typer.echo(f"scene: {'wrote' if made else 'already complete in'} {out}")


@app.command()
def plan(run_dir: RunDir, force: Force = False) -> None:
    """Plan the scan: waypoints.csv (elliptical scans, transits) and trajectory.csv (TOPP-RA, 100 Hz)."""
    from renderloop.planning.stage import run_plan
    from renderloop.rundir.files import read_config

    made = run_plan(run_dir, read_config(run_dir), force)
    typer.echo(f"plan: {'wrote' if made else 'already complete in'} {run_dir}")


@app.command()
def fly(run_dir: RunDir, force: Force = False) -> None:
    """Fly the trajectory in MuJoCo under cascade PID: flight.csv, groundtruth.txt (camera poses, TUM), plots."""
    from renderloop.rundir.files import read_config
    from renderloop.sim.stage import run_fly

    made = run_fly(run_dir, read_config(run_dir), force)
    typer.echo(f"fly: {'wrote' if made else 'already complete in'} {run_dir}")


THRESHOLD_HELP = f"Score threshold; default: the config's ({DetectorConfig.model_fields['score_threshold'].default})."
SHIPPED_NAME = "shipped"  # on the command line, wherever a model file goes: the model in the package
MODEL_HELP = f"ONNX model, or '{SHIPPED_NAME}' for the model in the package."


def _names(text: str) -> tuple[str, ...]:
    """A comma-separated option's names, in order, each once."""
    return tuple(dict.fromkeys(name.strip() for name in text.split(",")))


@contextmanager
def _progress_bar(label: str) -> Iterator[Callable[[int, int], None]]:
    """A rich bar on stderr; yields the (done, total) callback the stages take. The bar appears with the first
    report, so input refused before any work ends in its one line alone."""
    with ExitStack() as stack:
        shown: list = []

        def update(done: int, total: int) -> None:
            if not shown:
                bar = stack.enter_context(Progress(TextColumn(label), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                                                   TimeRemainingColumn(), console=Console(stderr=True)))
                shown.extend((bar, bar.add_task(label, total=None)))
            shown[0].update(shown[1], completed=done, total=total)

        yield update


Workers = Annotated[int, typer.Option(min=1, max=256, help="Renderer processes (one scene each).")]
Executor = Annotated[str, Choice(choices(parallel.Executor, "kind"), "local processes, or ray tasks on a Ray cluster.")]
Address = Annotated[str | None, typer.Option(help="Ray cluster address (with --executor ray); default: start a local one.")]


@app.command()
def render(
    run_dir: RunDir,
    backend: Annotated[str | None, Choice(choices(RendererConfig, "backend"), "cycles (photo-realistic) or raster (MuJoCo, fast); "
                                          "default: the config's.")] = None,
    workers: Workers = 1,
    executor: Executor = "local",
    address: Address = None,
    force: Force = False,
) -> None:
    """Render RGB, depth (planar, uint16 at 5000 per metre) and pepper instance masks at every pose of groundtruth.txt."""
    from renderloop.parallel import Executor as Parallel
    from renderloop.render.stage import run_render
    from renderloop.rundir.files import read_config

    config = read_config(run_dir)
    if backend is not None:
        config = config.override({"renderer": {"backend": backend}}, f"unknown backend {backend!r}")
    with _progress_bar("render") as progress:
        made = run_render(run_dir, config, force, progress, Parallel.of(executor, workers, address))
    typer.echo(f"render: {'wrote' if made else 'already complete in'} {run_dir}")


def _spec_option(name: str, flag: str | None = None) -> Any:
    """The `dataset` option of a DatasetSpec field: the model's description and default; a value not given (None) is
    the model's default, and the model checks the range of one given."""
    field = DatasetSpec.model_fields[name]
    default = ",".join(field.default) if name in ("styles", "environments") else field.default
    return typer.Option(*((flag,) if flag else ()), help=f"{field.description} Default: {default}.", show_default=False)


@app.command()
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
             "distance": distance, "sensor": sensor, "styles": None if styles is None else _names(styles),
             "environments": None if environments is None else _names(environments), "clutter": clutter, "close": close,
             "picked": picked}
    spec = DatasetSpec.of(**{name: value for name, value in given.items() if value is not None})
    with _progress_bar("dataset") as progress:
        made = build_dataset(out, images, spec, Parallel.of(executor, workers, address), force, progress)
    typer.echo(f"dataset: rendered {made} images, {images} in {out}")


@app.command("dataset-from-runs")
def dataset_runs(
    run_dirs: Annotated[list[Path], typer.Argument(help="Rendered run directories (with masks); the last --val-runs validate.",
                                                   show_default=False)],
    out: Annotated[Path, typer.Option(help="Dataset folder to (re)write: images/, labels/, annotations/.")],
    every: Annotated[int, typer.Option(min=1, max=1_000_000, help="Take every N-th frame of each run.")] = 1,
    val_runs: Annotated[int, typer.Option(min=0, help="How many of the last runs form the validation split.")] = 1,
) -> None:
    """A COCO detection dataset of the frames scan runs flew, boxes from their masks: fine-tuning data in the flight's own views."""
    from renderloop.dataset.from_runs import dataset_from_runs

    with _progress_bar("dataset") as progress:
        made = dataset_from_runs(run_dirs, out, every, val_runs, progress)
    typer.echo(f"dataset: {made} frames of {len(run_dirs)} runs in {out}")


def _train_extra(work: str, error: ImportError) -> UserError:
    """The one line for `work` without the train extra's packages."""
    why = f"{error.name} is missing" if error.name else str(error)  # a module that is there but fails to load has no name
    return UserError(f"{work} needs the train extra: pip install 'renderloop[train]' ({why})")


def _setting(name: str) -> Any:
    """The `train` option of a TrainSettings field: the model's description and default; a value not given (None) is
    the model's default, and the model checks the range of one given."""
    field = TrainSettings.model_fields[name]
    return typer.Option(help=f"{field.description} Default: {field.default}.", show_default=False)


@app.command()
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
        raise _train_extra("training", error) from None
    init = _named_model(init)
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


@app.command()
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
        raise _train_extra("quantizing", error) from None
    made = quantize_on_renders(_named_model(model), dataset_dirs, out, images, seed, force)
    typer.echo(f"quantize: wrote {made}")


def _named_model(model: Path | None) -> Path | None:
    """A model path as given on the command line, where the name `shipped` means the model in the package."""
    from renderloop.perception.detector import shipped_model

    return shipped_model() if model is not None and str(model) == SHIPPED_NAME else model


def _detector_options(model: Path | None, threshold: float | None, windows: str | None, mirror: bool | None,
                      min_box: float | None) -> dict:
    """The detector settings given of `--model`, `--threshold`, `--windows`, `--mirror` and `--min-box`, as config fields."""
    from renderloop.perception.tiling import layout_names, parse_layouts

    given = {"model": _named_model(model), "score_threshold": threshold, "windows": None if windows is None else layout_names(parse_layouts(windows)),
             "mirror": mirror, "min_box_px": min_box}
    return {name: value for name, value in given.items() if value is not None}


def _photo_detector(given: dict) -> DetectorConfig:
    """The detector settings of a verb on photos, or on runs it does not read the config of: the default config's,
    with those given on the command line."""
    return Config().override({"detector": given}).detector


@app.command()
def detect(
    run_dir: Annotated[Path | None, typer.Argument(help="Run directory with rendered frames.", show_default=False)] = None,
    images: Annotated[Path | None, typer.Option(help="Detect on this folder of photos instead (PNG/JPEG, no depth).")] = None,
    out: Annotated[Path | None, typer.Option(help="With --images: the JSON file to write.")] = None,
    model: Annotated[Path | None, typer.Option(help=MODEL_HELP + " Default: the config's, else the shipped one.")] = None,
    threshold: Annotated[float | None, typer.Option(min=0.0, max=1.0, help=THRESHOLD_HELP)] = None,
    windows: Windows = None,
    mirror: Mirror = None,
    min_box: MinBox = None,
    force: Force = False,
) -> None:
    """Detect peppers: detections.json (boxes, scores, ripe/unripe, 3D world points) of a run, or of a photo folder."""
    from renderloop.perception.photos import detect_photos
    from renderloop.perception.stage import run_detect
    from renderloop.rundir.files import read_config

    if (run_dir is None) == (images is None):
        raise UserError("give either a run directory or --images FOLDER --out FILE.json")
    given = _detector_options(model, threshold, windows, mirror, min_box)
    if images is not None:
        if out is None:
            raise UserError("--images needs --out FILE.json")
        with _progress_bar("detect") as progress:
            count = detect_photos(images, out, _photo_detector(given), force, progress)
        typer.echo(f"detect: {count} photos -> {out}")
        return
    config = read_config(run_dir).override({"detector": given})
    with _progress_bar("detect") as progress:  # settings given on the command line mean: detect again with them
        made = run_detect(run_dir, config, force or bool(given), progress)
    typer.echo(f"detect: {'wrote' if made else 'already complete in'} {run_dir}")


@app.command(name="threshold")
def choose_threshold(
    run_dirs: Annotated[list[Path], typer.Argument(help="Rendered runs the detector never trained on.", show_default=False)],
    model: Annotated[Path | None, typer.Option(help=MODEL_HELP + " Default: the shipped one.")] = None,
    windows: Windows = None,
    mirror: Mirror = None,
    min_box: MinBox = None,
    max_false: Annotated[float, typer.Option(min=0.0, max=1.0, help="Share of false detections allowed.")] = 0.05,
) -> None:
    """Choose the detector's score threshold on rendered runs: the lowest with at most --max-false of its detections false."""
    from renderloop.perception.detector import Detector
    from renderloop.perception.threshold import choose, format_scores, score_thresholds, search_run, threshold_text

    settings = _photo_detector(_detector_options(model, None, windows, mirror, min_box))
    detector = Detector(settings.model)
    with _progress_bar("threshold") as progress:
        runs = [search_run(run_dir, detector, settings, progress) for run_dir in run_dirs]
    scores = score_thresholds(runs)
    chosen = choose(scores, max_false)
    typer.echo(format_scores(scores, chosen))
    if chosen is None:
        raise UserError(f"no threshold up to {threshold_text(scores[-1].threshold)} keeps false detections at or under {max_false:.1%}")
    text = threshold_text(chosen.threshold)
    typer.echo(f"threshold: {text} (recall {chosen.recall:.3f}, {chosen.false_rate:.1%} false); "
               f"set detector.score_threshold or pass renderloop detect --threshold {text}")


@app.command()
def count(
    run_dir: RunDir,
    no_layout: Annotated[bool, typer.Option("--no-layout", help="Ignore the plant volumes: nearest table and LocalOutlierFactor instead.")] = False,
    force: Force = False,
) -> None:
    """Count the fruit per plant and row (OPTICS on detections.json): counts.json, harvest.json, counts/row_<id>.png."""
    from renderloop.counting.stage import run_count
    from renderloop.rundir.files import read_config, read_counts

    config = read_config(run_dir)
    made = run_count(run_dir, config.override({"counting": {"use_layout": False}}) if no_layout else config, force)
    total = read_counts(run_dir).total
    error = "n/a" if total.error_pct is None else f"{total.error_pct:+.1f} %"
    unseen = "" if total.unseen is None else f"; {total.unseen} never in view, {total.too_small} only too small"
    typer.echo(f"count: {'wrote' if made else 'already complete in'} {run_dir} "
               f"(ripe: {total.estimate} counted, {total.truth} true, {error}{unseen})")


@app.command()
def report(run_dir: RunDir, out: Annotated[Path | None, typer.Option(help="HTML file; default: DIR/report.html.")] = None,
           force: Annotated[bool, typer.Option("--force", help="Replace --out if it exists.")] = False) -> None:
    """Write report.html: one self-contained page of the run (yield table, plant cards, the greenhouse in 3D, detector, flight, times)."""
    from renderloop.report.html import write_report

    typer.echo(f"report: wrote {write_report(run_dir, out, force)}")


@app.command(name="eval")
def evaluate_seeds(
    out: Out,
    seeds: Annotated[str, typer.Option(help="Seeds to run: 0-19, 3, or 0,4,7-9.", show_default=False)],
    preset: Preset = "demo",
    config: ConfigFile = None,
    workers: Annotated[int, typer.Option(min=1, max=1024, help="Runs at once (processes, or Ray tasks).")] = 1,
    executor: Executor = "local",
    address: Address = None,
    force: Force = False,
    mission: Annotated[str | None, Choice(
        MISSIONS, "One, or several side by side: static,adaptive (default the config's mission.kind).", "--mission",
        several=True)] = None,
) -> None:
    """The paper's experiment (with --preset paper): one full run per seed, then the yield table (eval.csv, eval.json)."""
    from renderloop.evaluation.runner import evaluate
    from renderloop.evaluation.seeds import parse_seeds
    from renderloop.evaluation.table import EVAL_CSV, EVAL_JSON, format_table, write_eval
    from renderloop.parallel import Executor as Parallel

    parallel = Parallel.of(executor, workers, address)
    seed_list = parse_seeds(seeds)
    kinds = _names(mission) if mission else None
    for kind in kinds or ():
        load_config(preset, config, mission=kind)  # each mission's config is refused in one line, before any run
    base = load_config(preset, config)
    with _progress_bar("eval") as progress:
        scenarios = evaluate(base, seed_list, out, parallel, force, progress, kinds)
    write_eval(out, scenarios)
    typer.echo(format_table(scenarios))
    typer.echo(f"eval: wrote {out / EVAL_CSV} and {out / EVAL_JSON}")


@app.command()
def export(
    run_dir: RunDir,
    rosbag: Annotated[Path | None, typer.Option(help="ROS 2 bag directory to write (MCAP storage).")] = None,
    rerun: Annotated[Path | None, typer.Option(help="Rerun recording to write (.rrd).")] = None,
    every: Annotated[int, typer.Option(min=1, max=1_000_000, help="Images and clouds of every Nth frame only.")] = 1,
    force: Annotated[bool, typer.Option("--force", help="Replace outputs that exist.")] = False,
) -> None:
    """Export a run as a ROS 2 bag (RViz, Foxglove) and/or a Rerun recording; says what the run lacks (exit 2)."""
    from renderloop.export.command import export_run

    missing = export_run(run_dir, rosbag, rerun, every, force, typer.echo)
    if missing:
        raise UserError(f"{run_dir}: exported without {', '.join(missing)}")


@app.command(name="score-photos")
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
    force: Annotated[bool, typer.Option("--force", help="Replace a score that exists in --out.")] = False,
) -> None:
    """Score the detector on your labelled photos: recall, precision, F1, AP@0.5 (pycocotools) and the curve over thresholds."""
    from renderloop.perception.photo_score import OUTPUTS as PHOTO_SCORE_FILES
    from renderloop.perception.photo_score import score_photos, summary

    settings = _photo_detector(_detector_options(model, threshold, windows, mirror, min_box))
    with _progress_bar("score-photos") as progress:
        record = score_photos(folder, coco, out, settings, force, progress)
    for line in summary(record):
        typer.echo(f"score-photos: {line}")
    typer.echo(f"score-photos: wrote {out} ({', '.join(sorted(PHOTO_SCORE_FILES))})")


SCHEMA_FORMATS = ("table", "json")


@app.command(name="config")
def show_config(
    preset: Preset = "demo",
    config: ConfigFile = None,
    seed: Seed = None,
    schema: Annotated[bool, typer.Option("--schema", help="Print every field instead: its unit, default and range.")] = False,
    shape: Annotated[str | None, Choice(SCHEMA_FORMATS, "With --schema: a table by section to read (default), or the "
                                       "JSON Schema for programs.", "--format")] = None,
) -> None:
    """Print the resolved config (the preset, your YAML over it, the seed) as YAML, or the reference of every field."""
    if shape is not None and not schema:
        raise UserError(f"--format {shape} goes with --schema (the config itself prints as YAML)")
    if schema and shape == "json":
        typer.echo(json.dumps(config_schema(), indent=1))
        return
    if schema:
        from renderloop.config.reference import reference_text

        typer.echo(reference_text(min(100, max(60, shutil.get_terminal_size((100, 24)).columns))), nl=False)
        return
    typer.echo(load_config(preset, config, seed).to_yaml(), nl=False)


@app.command()
def run(out: Out, preset: Preset = "demo", config: ConfigFile = None, seed: Seed = None, force: Force = False,
        online: Annotated[bool, typer.Option("--online", help="Render and detect while flying (mission.online).")] = False,
        mission: MissionKind = None,
        workers: Annotated[int, typer.Option(min=1, max=1024, help="Renderer processes; with mission.split: rows, "
                                             "rows' missions at once (processes, or Ray tasks).")] = 1,
        executor: Executor = "local",
        address: Address = None) -> None:
    """Run every stage of the pipeline in order, skipping stages that are already complete; then write report.html
    (with mission.split: rows, one run a row in OUT/rows and the compartment's counts.json, harvest.json, fleet.json)."""
    from renderloop.parallel import Executor as Parallel
    from renderloop.report.words import run_summary
    from renderloop.rundir.files import read_counts

    resolved = load_config(preset, config, seed, online=online or None, mission=mission)
    parallel = Parallel.of(executor, workers, address)
    start = time.perf_counter()
    if resolved.mission.split == "rows":
        from renderloop.fleet.compartment import run_compartment
        from renderloop.rundir import names

        with _progress_bar("rows") as progress:
            run_compartment(out, resolved, force, parallel, progress)
        page = out / names.ROW_RUNS / "row_*" / names.REPORT  # each row's run has its report
    else:
        from renderloop.pipeline import run_pipeline
        from renderloop.report.html import write_report

        run_pipeline(out, resolved, force, Console(stderr=True), parallel)
        page = write_report(out, only_if_stale=True)  # not a stage: a report newer than every file it shows is kept
    typer.echo(f"run: {out} ({time.perf_counter() - start:.1f} s)")
    for line in run_summary(read_counts(out), page):
        typer.echo(line)


def _one_line(message: str) -> str:
    """`message` with every character that is not printable (a newline or escape in a path) written as its Python
    escape, as `errors.field_path` quotes a key: an error is one line whatever the user's paths hold."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in message)


def _error(message: str, code: int) -> None:
    print(f"renderloop: error: {_one_line(message)}", file=sys.stderr)
    sys.exit(code)


def main() -> None:
    try:
        code = app(standalone_mode=False)  # click's usage errors come here instead of a usage block
    except TyperException as error:  # an option out of range, a missing one: bad input like any other
        message = " ".join(error.format_message().split())
        if message:  # empty after the help that no arguments print
            _error(message, 2)
        sys.exit(2)
    except TyperAbort:  # Ctrl-C
        sys.exit(130)
    except UserError as error:
        _error(str(error), 2)
    except OSError as error:  # the machine, not the input: a full disk, a directory we may not write
        where = f"{final_path(Path(error.filename))}: " if error.filename else ""
        _error(f"{where}{error.strerror or error}", 1)
    sys.exit(code if isinstance(code, int) else 0)
