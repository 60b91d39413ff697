"""The verbs of a run: each stage of the pipeline, `run` for all of them, `eval` over seeds, `export` and `config`."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from renderloop.cli.common import (MISSIONS, MODEL_HELP, THRESHOLD_HELP, Address, Choice, ConfigFile, Enlargement, Executor, Force,
                                   MinBox, Mirror, MissionKind, Out, Preset, RunDir, Seed, Windows, Workers, app,
                                   detector_options, photo_detector, progress_bar, split_names)
from renderloop.config import RendererConfig, choices, config_schema, load_config
from renderloop.errors import UserError


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
    with progress_bar("render") as progress:
        made = run_render(run_dir, config, force, progress, Parallel.of(executor, workers, address))
    typer.echo(f"render: {'wrote' if made else 'already complete in'} {run_dir}")

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
    enlargement: Enlargement = None,
    force: Force = False,
) -> None:
    """Detect peppers: detections.json (boxes, scores, ripe/unripe, 3D world points) of a run, or of a photo folder."""
    from renderloop.perception.photos import detect_photos
    from renderloop.perception.stage import run_detect
    from renderloop.rundir.files import read_config

    if (run_dir is None) == (images is None):
        raise UserError("give either a run directory or --images FOLDER --out FILE.json")
    given = detector_options(model, threshold, windows, mirror, min_box, enlargement)
    if images is not None:
        if out is None:
            raise UserError("--images needs --out FILE.json")
        with progress_bar("detect") as progress:
            count = detect_photos(images, out, photo_detector(given), force, progress)
        typer.echo(f"detect: {count} photos -> {out}")
        return
    config = read_config(run_dir).override({"detector": given})
    with progress_bar("detect") as progress:  # settings given on the command line mean: detect again with them
        made = run_detect(run_dir, config, force or bool(given), progress)
    typer.echo(f"detect: {'wrote' if made else 'already complete in'} {run_dir}")

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
    kinds = split_names(mission) if mission else None
    for kind in kinds or ():
        load_config(preset, config, mission=kind)  # each mission's config is refused in one line, before any run
    base = load_config(preset, config)
    with progress_bar("eval") as progress:
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

        with progress_bar("rows") as progress:
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
