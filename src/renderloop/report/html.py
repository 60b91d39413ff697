"""`renderloop report DIR`: one self-contained report.html of a finished run.

Everything the page shows is inside it (images as data URIs, plotly.js inlined for the
3D view), so it can be mailed or archived alone and opens with no network. It reads
only through the typed readers of `renderloop.rundir.files` (and the frame PNGs through
`renderloop.render.frames`), so a run missing a stage's files is one line naming the
stage to run. From the top: the yield table (ripe fruit estimated against the truth,
per row, with the scan's misses), per-plant cards with each plant's best frame, the
greenhouse in 3D, the detector in words, the flight, the frames, the clusters, the
harvest plan, the stage times and the config.

The same files give the same page, byte for byte: two runs of one config give pages
that differ only in their stage times and the run directory's name.
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np
from PIL import Image

from renderloop.errors import UserError
from renderloop.io.atomic import write_text
from renderloop.pipeline import stages_of
from renderloop.render.camera import read_camera_info
from renderloop.report import words
from renderloop.report.frames import frames_section
from renderloop.report.plants import legend, plant_cards
from renderloop.report.view3d import greenhouse_figure, greenhouse_html
from renderloop.rundir import files, names
from renderloop.rundir.models import Counts, Estimate, Harvest, Mission
from renderloop.rundir.stage import claim
from renderloop.scene.model import read_scene

REQUIRED = (names.CONFIG, names.TOP_VIEW, names.FLIGHT_PATHS, names.TRACKING_ERROR, names.frames_index(names.DEPTH),
            names.DETECTION_SHEET, names.DETECTION_SCORES, names.COUNTS, names.HARVEST)
# What else the page is made from (the typed readers name the stage of a missing one); a report newer than all of
# them, and than REQUIRED, is current.
READS = (names.SCENE, names.POSES, names.FLIGHT, names.CAMERA_INFO, names.frames_index(names.RGB), names.DETECTIONS,
         names.TIMINGS, names.MISSION)
SECTIONS = (("yield", "Yield"), ("mission", "Mission"), ("plants", "Plants"), ("greenhouse", "Greenhouse in 3D"), ("detector", "Detector"),
            ("flight", "Scan flight"), ("frames", "Frames"), ("clusters", "Clusters"), ("harvest", "Harvest plan"),
            ("times", "Stage times"), ("config", "Config"))
STYLE = """
:root { --ok: #e8f5e9; --off: #fff1f0; --line: #d8d8d8; --muted: #666; }
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 0; color: #222; line-height: 1.45; }
main { max-width: 1200px; margin: 0 auto; padding: 0 1.2em 3em; }
nav { position: sticky; top: 0; z-index: 10; background: #fafafa; border-bottom: 1px solid var(--line); padding: 0.45em 1.2em;
      font-size: 0.92em; }
nav a { margin-right: 1.1em; color: #1f5fa8; text-decoration: none; white-space: nowrap; } nav a:hover { text-decoration: underline; }
h1 { margin: 0.7em 0 0.1em; font-size: 1.7em; } .lead { color: var(--muted); margin-top: 0; }
h2 { border-bottom: 1px solid var(--line); padding-bottom: 0.2em; margin-top: 1.8em; scroll-margin-top: 2.5em; }
h3 { margin: 0.2em 0 0.4em; font-size: 1.08em; } .sub { color: var(--muted); font-weight: normal; font-size: 0.9em; }
table { border-collapse: collapse; margin: 0.5em 0; } td, th { border: 1px solid var(--line); padding: 0.3em 0.65em; text-align: right; }
th { background: #f2f2f2; font-weight: 600; } td.left, th.left { text-align: left; }
tr.off td { background: var(--off); } tr.total td { font-weight: 600; border-top: 2px solid #999; }
table.yield { font-size: 1.05em; } table.yield td { white-space: nowrap; } table.yield th { vertical-align: bottom; max-width: 9em; }
.headline { font-size: 1.25em; margin: 0.4em 0 0.2em; } .headline b { font-size: 1.15em; }
img { max-width: 100%; border: 1px solid #ddd; } figure { margin: 0.5em 0; } figcaption { color: var(--muted); font-size: 0.9em; }
pre { background: #f7f7f7; padding: 0.8em; overflow-x: auto; font-size: 0.85em; }
.cards { display: grid; grid-template-columns: repeat(auto-fill, minmax(300px, 1fr)); gap: 0.9em; }
.card { border: 1px solid var(--line); border-radius: 6px; padding: 0.7em 0.8em; border-top: 5px solid #c62828; }
.card.exact { border-top-color: #2e7d32; } .card table { width: 100%; font-size: 0.95em; } .card img { width: 100%; }
.card tr.ok td { background: var(--ok); } .misses, .noframe { color: var(--muted); font-size: 0.9em; margin: 0.3em 0; }
.legend span { display: inline-block; margin-right: 1.2em; } .swatch { display: inline-block; width: 1.5em; height: 0.8em;
  vertical-align: middle; margin-right: 0.4em; border: 2px solid; background: #333; box-shadow: 0 0 0 3px #333; }
.view3d { border: 1px solid var(--line); border-radius: 6px; }
.bar { display: inline-block; height: 0.8em; background: #7aa6d6; vertical-align: middle; }
dl.scores { display: grid; grid-template-columns: max-content max-content; gap: 0.25em 1.5em; } dl.scores dd { margin: 0; font-weight: 600; }
details summary { cursor: pointer; color: #1f5fa8; }
.wide figure { margin: 0.8em 0 1.4em; } .wide img { width: 100%; }
.frames { display: grid; grid-template-columns: repeat(var(--columns), minmax(0, 1fr)); gap: 0.2em 0.6em; }
.frames figure { margin: 0 0 0.4em; } .frames img { width: 100%; image-rendering: auto; }
.frames .colhead { font-weight: 600; }
.depthscale { display: flex; align-items: center; flex-wrap: wrap; gap: 0.4em 1.2em; margin: 0.6em 0 0.9em; }
.depthscale .ramp { width: 24em; } .depthscale .gradient { height: 1em; border: 1px solid #999; }
.depthscale .ticks { display: flex; justify-content: space-between; font-size: 0.85em; }
.depthscale .off i { display: inline-block; width: 1.4em; height: 1em; border: 1px solid #999; vertical-align: middle;
  margin-right: 0.4em; }
"""


def _png(path: Path, alt: str, caption: str = "") -> str:
    """A figure of the run, inline; re-encoded with a 256-colour palette, which plots and renders barely show and which
    makes them about a third of their size."""
    with Image.open(path) as image:
        buffer = io.BytesIO()
        image.convert("RGB").quantize(256, method=Image.Quantize.FASTOCTREE).save(buffer, format="PNG")
    data = base64.b64encode(buffer.getvalue()).decode("ascii")
    image = f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'
    return f"<figure>{image}<figcaption>{html.escape(caption)}</figcaption></figure>" if caption else image


def _table(headers: list[str], rows: list[list[object]], off: list[bool] | None = None, css: str = "",
           total: bool = False) -> str:
    """Rows of already formatted cells, the first column left-aligned; `off` marks rows whose estimate is wrong,
    `total` makes the last row a total."""
    def attribute(name: str, value: str) -> str:
        return f' {name}="{value}"' if value else ""

    head = "".join(f"<th{attribute('class', 'left' if i == 0 else '')}>{html.escape(h)}</th>" for i, h in enumerate(headers))
    body = []
    for index, row in enumerate(rows):
        cells = "".join(f"<td{attribute('class', 'left' if i == 0 else '')}>{html.escape(str(v))}</td>" for i, v in enumerate(row))
        classes = [name for name, on in (("off", bool(off and off[index])), ("total", total and index == len(rows) - 1)) if on]
        body.append(f"<tr{attribute('class', ' '.join(classes))}>{cells}</tr>")
    return f"<table{attribute('class', css)}><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _misses(plants: list, key: str) -> str:
    values = [getattr(plant, key) for plant in plants]
    return "n/a" if any(v is None for v in values) else str(sum(values))


def _yield_section(counts: Counts) -> str:
    """The table people open the report for: ripe fruit estimated against the truth, per row and in all."""
    total = counts.total
    headers = ["Row", "Ripe fruit estimated", "Ripe fruit true", "Error, % of true", "Plants counted exactly",
               "Ripe never in view", f"Ripe only seen too small (under {words.MIN_SIDE} x {words.MIN_SIDE} px)",
               "Unripe estimated", "Unripe true", "Ripe fruit, the count's 90 % range"]
    rows, off = [], []
    for row in counts.rows:
        plants = [plant for plant in counts.plants if plant.row == row.id]
        error = 100 * (row.estimate - row.truth) / row.truth if row.truth else None
        rows.append([f"row {row.id}", row.estimate, row.truth, words.signed_pct(error),
                     words.share(sum(p.estimate == p.truth for p in plants), len(plants)),
                     _misses(plants, "unseen"), _misses(plants, "too_small"), row.unripe_estimate, row.unripe_truth,
                     words.count_range(row.interval)])
        off.append(row.estimate != row.truth)
    rows.append(["all rows", total.estimate, total.truth, words.signed_pct(total.error_pct), words.exact_plants(counts),
                 "n/a" if total.unseen is None else total.unseen, "n/a" if total.too_small is None else total.too_small,
                 total.unripe_estimate, total.unripe_truth, words.count_range(total.interval)])
    off.append(total.estimate != total.truth)
    headline = (f'<p class="headline">Ripe yield: <b>{total.estimate}</b> estimated, <b>{total.truth}</b> true '
                f"({html.escape(words.signed_pct(total.error_pct))}); plants counted exactly: {html.escape(words.exact_plants(counts))}.</p>")
    return (_table(headers, rows, off, css="yield", total=True) + headline
            + f"<p>{html.escape(words.misses_sentence(counts))}</p>"
            + f"<p>{html.escape(words.tally_sentence(counts.detections))}</p>")


def _interval(estimate: Estimate) -> str:
    return str(estimate.estimate) if estimate.low == estimate.high else f"{estimate.estimate} ({estimate.low}-{estimate.high})"


def _mission_section(mission: Mission, counts: Counts) -> str:
    """What the adaptive mission decided, plant by plant: the count after the first pass, the views it added and why."""
    truth = {plant.id: plant.truth for plant in counts.plants}
    headers = ["Plant", "Row", "After the first pass (interval)", "Views added", "Why", "In the end (interval)",
               "Ripe fruit true"]
    rows, off = [], []
    for plant in mission.plants:
        added = sum(len(r.views) for r in plant.rounds)
        why = "; ".join(f"{r.why} (at {r.decided_at:.1f} s)" for r in plant.rounds) or (plant.fallback or "settled")
        rows.append([f"plant {plant.id}", plant.row, _interval(plant.first_pass), added, why, _interval(plant.final),
                     truth.get(plant.id, "n/a")])
        off.append(plant.final.estimate != truth.get(plant.id))
    added = sum(len(r.views) for plant in mission.plants for r in plant.rounds)
    return (f"<p>A coarse first pass took {mission.first_pass_frames} frames; the mission then looked again at "
            f"{sum(bool(p.rounds) for p in mission.plants)} of {len(mission.plants)} plants from {added} added views "
            f"({mission.frames} frames in all, {html.escape(words.seconds(mission.flight_time_s))} of flight). "
            "The interval is the counter's 90 % range for the plant's ripe count.</p>"
            + _table(headers, rows, off) + _harvest_updates(mission))


def _harvest_updates(mission: Mission) -> str:
    """The harvest plan after each decision of the mission, as the counts settled."""
    if not mission.harvest:
        return ""
    rows = [[words.seconds(update.time), update.row, "first pass" if update.round == 0 else f"round {update.round}",
             update.plants_counted, ", ".join(map(str, update.stops)) or "none", update.expected_ripe,
             f"{update.total_distance:.1f} m"] for update in mission.harvest]
    headers = ["At", "Row decided", "After", "Plants counted", "Plants to bring in, in order", "Ripe fruit expected",
               "Round trip"]
    return ("<p>The harvest plan as the counts settled: after each decision, the plants counted so far that are "
            "expected to carry enough ripe fruit, in the order to bring them in.</p>" + _table(headers, rows))


def _flight_sentence(flight: dict[str, np.ndarray]) -> str:
    t = flight["t"]
    if len(t) < 2:
        return "The flight log is empty."
    body = np.column_stack([flight["x"], flight["y"], flight["z"]])
    length = float(np.linalg.norm(np.diff(body, axis=0), axis=1).sum())
    error = 100 * np.linalg.norm(np.column_stack([flight["err_x"], flight["err_y"], flight["err_z"]]), axis=1)
    camera = 100 * flight["cam_err"]
    contacts = int(np.count_nonzero(np.diff(np.r_[0, flight["contacts"] > 0].astype(int)) == 1))
    return (f"The scan took {words.seconds(float(t[-1] - t[0]))} over {length:.1f} m of path. The body was a median "
            f"{np.median(error):.1f} cm off the planned path ({error.max():.1f} cm at worst), the camera a median "
            f"{np.median(camera):.1f} cm off its planned place ({camera.max():.1f} cm at worst). "
            f"Rotors saturated {100 * float(np.mean(flight['saturated'] > 0)):.1f} % of the time; "
            + ("the robot never touched anything." if contacts == 0 else
               f"the robot touched something {contacts} time{'s' if contacts != 1 else ''}."))


def _harvest_section(harvest: Harvest) -> str:
    rows = [[f"plant {stop.id}", stop.row, stop.expected_ripe, f"{stop.leg_distance:.2f}"] for stop in harvest.stops]
    if not rows:
        return f"<p>No plant is expected to carry {harvest.min_ripe} or more ripe fruit: nothing to bring in.</p>"
    return (f"<p>The plants expected to carry {harvest.min_ripe} or more ripe fruit, in the order to bring them to the "
            f"workstation: {harvest.total_expected_ripe} ripe fruit in all, {harvest.total_distance:.1f} m of travel "
            f"({harvest.return_distance:.1f} m of it back to the workstation). Distances: {html.escape(harvest.distance)}.</p>"
            + _table(["Plant, in visiting order", "Row", "Ripe fruit expected", "Leg from the previous stop, m"], rows))


def _times_section(timings: dict[str, float], order: tuple[str, ...]) -> str:
    if not timings:
        return "<p>Not recorded: <code>renderloop run</code> writes them to timings.json.</p>"
    stages = [name for name in order if name in timings] + sorted(set(timings) - set(order))
    longest = max(timings.values()) or 1.0
    rows = "".join(
        f'<tr><td class=left>{html.escape(name)}</td><td class=left>{html.escape(words.STAGE_WORDS.get(name, ""))}</td>'
        f"<td>{html.escape(words.seconds(timings[name]))}</td>"
        f'<td class=left><span class="bar" style="width:{12 * timings[name] / longest:.2f}em"></span></td></tr>'
        for name in stages)
    return (f"<p>{html.escape(words.timing_sentence(timings, order))} A stage that was already complete keeps the "
            "time of the run that made it.</p>"
            f"<table><thead><tr><th class=left>Stage</th><th class=left>What it does</th><th>Time</th><th></th></tr></thead>"
            f"<tbody>{rows}</tbody></table>")


def build_report(run_dir: Path) -> str:
    run_dir = Path(run_dir)
    config = files.read_config(run_dir)  # a run directory at all
    files.require(run_dir, REQUIRED)
    config_text = (run_dir / names.CONFIG).read_text(encoding="utf-8")
    scene = read_scene(run_dir)
    times, poses = files.read_poses(run_dir)
    flight = files.read_flight(run_dir)
    intrinsics = read_camera_info(run_dir)
    detections = files.read_detections(run_dir, len(poses))
    scores = files.read_detection_scores(run_dir)
    counts = files.read_counts(run_dir)
    harvest = files.read_harvest(run_dir)
    timings = files.read_timings(run_dir)
    row_plots = [(row.id, run_dir / names.row_plot(row.id)) for row in counts.rows if (run_dir / names.row_plot(row.id)).is_file()]

    mission = files.read_mission(run_dir) if config.mission.kind == "adaptive" else None
    views = {view.frame: f"plant {plant.id}, {r.why}" for plant in mission.plants for r in plant.rounds
             for view in r.views if view.frame is not None} if mission else None
    figure = greenhouse_figure(scene, counts, detections, flight, times, poses, intrinsics, views)
    score_list = "".join(f"<dt>{html.escape(k)}</dt><dd>{html.escape(v)}</dd>" for k, v in words.score_lines(scores))
    lead = (f"{len(scene.rows)} row{'s' if len(scene.rows) != 1 else ''}, {len(scene.plants)} plants, "
            f"{sum(p.ripe for p in scene.peppers)} ripe and {sum(not p.ripe for p in scene.peppers)} unripe fruit; "
            f"seed {config.seed}; {len(poses)} frames of {intrinsics.width} x {intrinsics.height} px "
            f"({config.renderer.backend} renderer){'; rendered and detected while flying' if config.mission.online else ''}.")
    body = {
        "yield": _yield_section(counts),
        "mission": (_mission_section(mission, counts) if mission else
                    "<p>The static scan: every plant seen along the planned path at the camera's rate "
                    "(<code>renderloop run --mission adaptive</code> looks again where the count is uncertain).</p>"),
        "plants": ("<p>Each plant's ripe and unripe count beside its truth, and the frame that shows it best: the one with the "
                   "most detections of its fruit (then the most of its fruit in view).</p>" + legend()
                   + plant_cards(run_dir, scene, counts, detections)),
        "greenhouse": ("<p>Drag to turn, scroll to zoom, click a legend entry to hide it (the plant volumes start hidden). "
                       "Hover a point for what it is.</p>"
                       f'<div class="view3d">{greenhouse_html(figure)}</div>'
                       "<details><summary>The same greenhouse from above, as a still picture</summary>"
                       + _png(run_dir / names.TOP_VIEW, "top view") + "</details>"),
        "detector": ("<p>The detections of every frame scored against the instance masks (the simulator's truth); a detection "
                     "matches a fruit when the boxes overlap by half (IoU 0.5).</p>"
                     f'<dl class="scores">{score_list}</dl>'
                     f"<p>{html.escape(words.recall_sentence(scores, counts))}</p>"
                     + _png(run_dir / names.DETECTION_SHEET, "detections and truth",
                            "Frames spread over the scan: the detector's boxes (left) and the true fruit from the masks "
                            "(right; grey: too small to find).")),
        "flight": (f"<p>{html.escape(_flight_sentence(flight))}</p><div class='wide'>"
                   + _png(run_dir / names.FLIGHT_PATHS, "planned and flown paths", "The planned and the flown path.")
                   + _png(run_dir / names.TRACKING_ERROR, "tracking error",
                          "How far the robot was from where the plan had it, over time.") + "</div>"),
        "frames": frames_section(run_dir, times),
        "clusters": ("<p>How the 3D points of each row were clustered into fruit: top and side views, the true fruit as open "
                     "circles.</p><div class='wide'>"
                     + "".join(_png(path, f"row {row}", f"Row {row}.") for row, path in row_plots) + "</div>"
                     if row_plots else "<p>No cluster plots in this run.</p>"),
        "harvest": _harvest_section(harvest),
        "times": _times_section(timings, tuple(stage.name for stage in stages_of(config))),
        "config": ("<details><summary>The resolved config this run was made with (config.yaml)</summary><pre>"
                   + html.escape(config_text) + "</pre></details>"),
    }
    nav = "".join(f'<a href="#{key}">{html.escape(title)}</a>' for key, title in SECTIONS)
    sections = "".join(f'<section id="{key}"><h2>{html.escape(title)}</h2>{body[key]}</section>'
                       for key, title in SECTIONS)
    title = f"renderloop run {run_dir.name}"
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body><nav>{nav}</nav><main>"
            f"<h1>Sweet-pepper yield</h1><p class='lead'>Run <code>{html.escape(str(run_dir.name))}</code>: {html.escape(lead)}</p>"
            f"{sections}</main></body></html>\n")


def current(run_dir: Path, out: Path) -> bool:
    """Is `out` a report of the run's present files (newer than every file it is made from)?"""
    if not Path(out).is_file():
        return False
    sources = [Path(run_dir) / name for name in (*REQUIRED, *READS)]
    sources += list((Path(run_dir) / names.COUNT_PLOTS).glob("*.png"))
    newest = max((path.stat().st_mtime_ns for path in sources if path.is_file()), default=0)
    return Path(out).stat().st_mtime_ns >= newest


def write_report(run_dir: Path, out: Path | None = None, force: bool = False, only_if_stale: bool = False) -> Path:
    """report.html in the run directory, or `out`: a file of the user's is replaced only with `force`.
    `only_if_stale`: keep a report.html that is newer than every file it shows (what `renderloop run` does)."""
    inside = out is None
    if inside:
        out = claim(run_dir, write=False) / names.REPORT  # checked only: a run that fails to read leaves nothing behind
    elif Path(out).exists() and not force:
        raise UserError(f"{out}: exists; use --force to replace it")
    if only_if_stale and current(run_dir, out):
        return Path(out)
    page = build_report(run_dir)
    if inside:
        claim(run_dir)
    write_text(Path(out), page)
    return Path(out)
