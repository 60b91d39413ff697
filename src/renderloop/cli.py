"""The `renderloop` command: one verb per pipeline stage, plus `run` for all of them.

Bad input ends in one line on stderr and exit code 2 (UserError); an operating-system
failure such as a full disk or a read-only directory in one line and exit code 1.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from renderloop import __version__
from renderloop.config import PRESETS, load_config
from renderloop.errors import UserError
from renderloop.io.rundir import read_config
from renderloop.pipeline import run_pipeline
from renderloop.planning.stage import run_plan
from renderloop.render.stage import run_render
from renderloop.scene.stage import run_scene
from renderloop.sim.stage import run_fly

app = typer.Typer(
    name="renderloop",
    help="Render-in-the-loop aerial robotics simulator: sweet-pepper yield estimation in a greenhouse.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

Preset = Annotated[str, typer.Option(help=f"Config preset: {', '.join(PRESETS)}.")]
ConfigFile = Annotated[Optional[Path], typer.Option("--config", help="YAML file whose fields override the preset.")]
Seed = Annotated[Optional[int], typer.Option(help="Seed of every random choice (overrides the config's).")]
Out = Annotated[Path, typer.Option(help="Run directory to write into.")]
Force = Annotated[bool, typer.Option("--force", help="Redo stages whose outputs already exist.")]
RunDir = Annotated[Path, typer.Argument(help="Run directory made by `renderloop scene`.", show_default=False)]


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
    resolved = load_config(preset, config, seed)
    made = run_scene(out, resolved, force)
    typer.echo(f"scene: {'wrote' if made else 'already complete in'} {out}")


@app.command()
def plan(run_dir: RunDir, force: Force = False) -> None:
    """Plan the scan: waypoints.csv (elliptical scans, transits) and trajectory.csv (TOPP-RA, 100 Hz)."""
    made = run_plan(run_dir, read_config(run_dir), force)
    typer.echo(f"plan: {'wrote' if made else 'already complete in'} {run_dir}")


@app.command()
def fly(run_dir: RunDir, force: Force = False) -> None:
    """Fly the trajectory in MuJoCo under cascade PID: flight.csv, groundtruth.txt (camera poses, TUM), plots."""
    made = run_fly(run_dir, read_config(run_dir), force)
    typer.echo(f"fly: {'wrote' if made else 'already complete in'} {run_dir}")


@app.command()
def render(
    run_dir: RunDir,
    backend: Annotated[Optional[str], typer.Option(help="cycles (photo-realistic) or raster (MuJoCo, fast); default: the config's.")] = None,
    workers: Annotated[int, typer.Option(min=1, max=256, help="Renderer processes (one scene each).")] = 1,
    executor: Annotated[str, typer.Option(help="local processes, or ray tasks on a Ray cluster.")] = "local",
    address: Annotated[Optional[str], typer.Option(help="Ray cluster address (with --executor ray); default: start a local one.")] = None,
    force: Force = False,
) -> None:
    """Render RGB, depth (planar, uint16 at 5000 per metre) and pepper instance masks at every pose of groundtruth.txt."""
    with Progress(TextColumn("render"), BarColumn(), TextColumn("{task.completed}/{task.total}"), TimeRemainingColumn(),
                  console=Console(stderr=True)) as bar:
        task = bar.add_task("render", total=None)
        made = run_render(run_dir, read_config(run_dir), force, backend, workers, executor, address,
                          progress=lambda done, total: bar.update(task, completed=done, total=total))
    typer.echo(f"render: {'wrote' if made else 'already complete in'} {run_dir}")


@app.command()
def run(out: Out, preset: Preset = "demo", config: ConfigFile = None, seed: Seed = None, force: Force = False) -> None:
    """Run every stage of the pipeline in order, skipping stages that are already complete."""
    resolved = load_config(preset, config, seed)
    seconds = run_pipeline(out, resolved, force, Console(stderr=True))
    typer.echo(f"run: {out} ({sum(seconds.values()):.1f} s)")


def main() -> None:
    try:
        app()
    except UserError as error:
        print(f"renderloop: error: {error}", file=sys.stderr)
        sys.exit(2)
    except OSError as error:
        where = f" {error.filename}" if error.filename else ""
        print(f"renderloop: error:{where} {error.strerror or error}", file=sys.stderr)
        sys.exit(1)
