"""The typer app of `renderloop` and what its verbs share: help that reads as the command is typed, options of a
fixed set of values, the option types several verbs take, the progress bar, and the detector options of the
command line. The verbs are in `stages` (a run's) and `detector` (datasets, training, scoring)."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from typer.core import TyperCommand, TyperGroup

from renderloop import __version__
from renderloop import parallel
from renderloop.config import PRESETS, Config, DetectorConfig, MissionConfig, choices
from renderloop.errors import UserError, did_you_mean

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
        for name in split_names(value) if several else (value,):
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
                                             "e.g. 2x2,3x2; none: whole images only; default: the config's detector.windows.")]
Mirror = Annotated[bool | None, typer.Option("--mirror/--no-mirror", help="Also search each image mirrored; default: the config's.",
                                             show_default=False)]
MinBox = Annotated[float | None, typer.Option("--min-box", min=0.0, help="Shorter side in px a detection's box needs; "
                                              "default: the config's (0: every box).")]
Enlargement = Annotated[float | None, typer.Option(
    "--window-enlargement", min=1.0, max=16.0, help="Most times the network input may enlarge a window for its layout to "
    "be searched; default: the config's detector.max_window_enlargement (1.5: a 320x240 image gets no windows).")]


def _version(value: bool) -> None:
    if value:
        typer.echo(f"renderloop {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version.")] = False,
) -> None:
    """Render-in-the-loop aerial robotics simulator: sweet-pepper yield estimation in a greenhouse."""


THRESHOLD_HELP = f"Score threshold; default: the config's ({DetectorConfig.model_fields['score_threshold'].default})."
SHIPPED_NAME = "shipped"  # on the command line, wherever a model file goes: the model in the package
MODEL_HELP = f"ONNX model, or '{SHIPPED_NAME}' for the model in the package."


def split_names(text: str) -> tuple[str, ...]:
    """A comma-separated option's names, in order, each once."""
    return tuple(dict.fromkeys(name.strip() for name in text.split(",")))


@contextmanager
def progress_bar(label: str) -> Iterator[Callable[[int, int], None]]:
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


def train_extra(work: str, error: ImportError) -> UserError:
    """The one line for `work` without the train extra's packages."""
    why = f"{error.name} is missing" if error.name else str(error)  # a module that is there but fails to load has no name
    return UserError(f"{work} needs the train extra: pip install 'renderloop[train]' ({why})")

def named_model(model: Path | None) -> Path | None:
    """A model path as given on the command line, where the name `shipped` means the model in the package."""
    from renderloop.perception.detector import shipped_model

    return shipped_model() if model is not None and str(model) == SHIPPED_NAME else model


def detector_options(model: Path | None, threshold: float | None, windows: str | None, mirror: bool | None,
                      min_box: float | None, enlargement: float | None) -> dict:
    """The detector settings given of `--model`, `--threshold`, `--windows`, `--mirror`, `--min-box` and
    `--window-enlargement`, as config fields."""
    from renderloop.perception.tiling import layout_names, parse_layouts

    given = {"model": named_model(model), "score_threshold": threshold, "windows": None if windows is None else layout_names(parse_layouts(windows)),
             "mirror": mirror, "min_box_px": min_box, "max_window_enlargement": enlargement}
    return {name: value for name, value in given.items() if value is not None}


def photo_detector(given: dict) -> DetectorConfig:
    """The detector settings of a verb on photos, or on runs it does not read the config of: the default config's,
    with those given on the command line."""
    return Config().override({"detector": given}).detector
