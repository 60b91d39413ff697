"""`renderloop report DIR`: one self-contained report.html of a finished run.

Everything the page shows is inside it (PNGs as data URIs, tables as HTML), so it
can be mailed or archived alone and opens with no network. It reads only files the
stages wrote: the config, the top view, the flight figures, the contact sheet, the
detection sheet and scores, the count table and the cluster plots, the harvest plan
and the seconds each stage took (`timings.json`, written by `renderloop run`).
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

from renderloop.errors import UserError
from renderloop.io.atomic import write_text
from renderloop.pipeline import ONLINE_STAGES, STAGES
from renderloop.rundir import files, names
from renderloop.rundir.models import Counts, Harvest
from renderloop.rundir.stage import claim

STAGE_ORDER = tuple(dict.fromkeys(stage.name for stage in (*STAGES, *ONLINE_STAGES)))
REQUIRED = (names.CONFIG, names.TOP_VIEW, names.FLIGHT_PATHS, names.TRACKING_ERROR, names.CONTACT_SHEET,
            names.DETECTION_SHEET, names.DETECTION_SCORES, names.COUNTS, names.HARVEST)
STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1200px; color: #222; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: 0.2em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0; } td, th { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f2f2f2; } td.left, th.left { text-align: left; } tr.off td { background: #fff1f0; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.3em 0; } pre { background: #f7f7f7; padding: 0.8em; overflow-x: auto; }
.figures { display: grid; grid-template-columns: repeat(auto-fit, minmax(520px, 1fr)); gap: 0.8em; }
"""


def _image(path: Path, alt: str) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _table(headers: list[str], rows: list[list[object]], off: list[bool] | None = None) -> str:
    head = "".join(f'<th class="{"left" if i == 0 else ""}">{html.escape(h)}</th>' for i, h in enumerate(headers))
    body = []
    for index, row in enumerate(rows):
        cells = "".join(f'<td class="{"left" if i == 0 else ""}">{html.escape(_fmt(v))}</td>' for i, v in enumerate(row))
        body.append(f'<tr class="{"off" if off and off[index] else ""}">{cells}</tr>')
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def _fmt(value: object) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.3g}" if abs(value) < 1000 else f"{value:.0f}"
    return str(value)


def _counts_section(counts: Counts) -> str:
    total = counts.total
    rows = [[p.id, p.row, p.estimate, p.truth, p.unripe_estimate, p.unripe_truth] for p in counts.plants]
    per_row = [[r.id, r.estimate, r.truth, r.unripe_estimate, r.unripe_truth, r.detections] for r in counts.rows]
    summary = _table(["yield", "estimate", "truth", "error %"],
                     [["ripe (the yield)", total.estimate, total.truth, total.error_pct],
                      ["unripe", total.unripe_estimate, total.unripe_truth, None]])
    exact = "n/a" if total.exact_plants is None else f"{100 * total.exact_plants:.0f} %"
    return (f"{summary}<p>Plants counted exactly: {exact}.</p>"
            "<h3>Per row</h3>" + _table(["row", "ripe estimate", "ripe truth", "unripe estimate", "unripe truth", "ripe points"], per_row,
                                        [r[1] != r[2] for r in per_row])
            + "<h3>Per plant</h3>" + _table(["plant", "row", "ripe estimate", "ripe truth", "unripe estimate", "unripe truth"], rows,
                                            [r[2] != r[3] for r in rows]))


def _harvest_section(harvest: Harvest) -> str:
    rows = [[stop.id, stop.row, stop.expected_ripe, stop.leg_distance] for stop in harvest.stops]
    return (_table(["plant (in visiting order)", "row", "expected ripe", "leg distance, m"], rows)
            + f"<p>Back to the workstation {_fmt(harvest.return_distance)} m; total {_fmt(harvest.total_distance)} m "
            f"({html.escape(harvest.distance)}); expected ripe yield {harvest.total_expected_ripe}.</p>")


def build_report(run_dir: Path) -> str:
    run_dir = Path(run_dir)
    files.read_config(run_dir)  # a run directory at all
    files.require(run_dir, REQUIRED)
    config = (run_dir / names.CONFIG).read_text(encoding="utf-8")
    scores = files.read_detection_scores(run_dir)
    counts = files.read_counts(run_dir)
    harvest = files.read_harvest(run_dir)
    timings = files.read_timings(run_dir)
    row_plots = [run_dir / names.row_plot(row.id) for row in counts.rows if (run_dir / names.row_plot(row.id)).is_file()]
    sections = [
        f"<h1>renderloop run: {html.escape(run_dir.name)}</h1>",
        "<h2>Yield</h2>" + _counts_section(counts),
        "<h2>Greenhouse</h2>" + _image(run_dir / names.TOP_VIEW, "top view"),
        "<h2>Scan flight</h2><div class='figures'>" + _image(run_dir / names.FLIGHT_PATHS, "planned and flown paths")
        + _image(run_dir / names.TRACKING_ERROR, "tracking error") + "</div>",
        "<h2>Frames</h2>" + _image(run_dir / names.CONTACT_SHEET, "contact sheet"),
        "<h2>Detections</h2>" + _table(["figure", "value"], [[k, v] for k, v in scores.model_dump().items()])
        + _image(run_dir / names.DETECTION_SHEET, "detections (left) and truth (right)"),
        "<h2>Clusters per row</h2><div class='figures'>" + "".join(_image(p, p.stem) for p in row_plots) + "</div>",
        "<h2>Harvest plan</h2>" + _harvest_section(harvest),
        "<h2>Stage times</h2>" + (_table(["stage", "seconds"], [[name, timings[name]] for name in STAGE_ORDER if name in timings]) if timings
                                   else "<p>Not recorded (<code>renderloop run</code> writes them to timings.json).</p>"),
        "<h2>Config</h2><pre>" + html.escape(config) + "</pre>",
    ]
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>renderloop report</title>"
            f"<style>{STYLE}</style></head><body>{''.join(sections)}</body></html>\n")


def write_report(run_dir: Path, out: Path | None = None, force: bool = False) -> Path:
    """report.html in the run directory, or `out`: a file of the user's is replaced only with `force`."""
    if out is None:
        out = claim(run_dir) / names.REPORT
    elif Path(out).exists() and not force:
        raise UserError(f"{out}: exists; use --force to replace it")
    page = build_report(run_dir)
    write_text(Path(out), page)
    return Path(out)
