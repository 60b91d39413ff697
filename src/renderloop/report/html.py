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
import json
from pathlib import Path

from renderloop.errors import UserError
from renderloop.io import rundir
from renderloop.io.atomic import write_text
from renderloop.pipeline import STAGES, TIMINGS

REQUIRED = ("config.yaml", "scene_topview.png", "flight_paths.png", "tracking_error.png", "contact_sheet.png",
            "detections.png", "detection_scores.json", "counts.json", "harvest.json")
STAGE_OF = {"config.yaml": "scene", "scene_topview.png": "scene", "flight_paths.png": "fly", "tracking_error.png": "fly",
            "contact_sheet.png": "render", "detections.png": "detect", "detection_scores.json": "detect",
            "counts.json": "count", "harvest.json": "count"}
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


def _read_json(path: Path) -> dict:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        raise UserError(f"{path}: not a readable JSON file") from None


def _counts_section(counts: dict) -> str:
    total = counts["total"]
    plants = counts["plants"]
    rows = [[p["id"], p["row"], p["estimate"], p["truth"], p["unripe_estimate"], p["unripe_truth"]] for p in plants]
    per_row = [[r["id"], r["estimate"], r["truth"], r["unripe_estimate"], r["unripe_truth"], r["detections"]] for r in counts["rows"]]
    summary = _table(["yield", "estimate", "truth", "error %"],
                     [["ripe (the yield)", total["estimate"], total["truth"], total["error_pct"]],
                      ["unripe", total["unripe_estimate"], total["unripe_truth"], None]])
    return (f"{summary}<p>Plants counted exactly: {100 * total['exact_plants']:.0f} %.</p>"
            "<h3>Per row</h3>" + _table(["row", "ripe estimate", "ripe truth", "unripe estimate", "unripe truth", "ripe points"], per_row,
                                        [r[1] != r[2] for r in per_row])
            + "<h3>Per plant</h3>" + _table(["plant", "row", "ripe estimate", "ripe truth", "unripe estimate", "unripe truth"], rows,
                                            [r[2] != r[3] for r in rows]))


def _harvest_section(harvest: dict) -> str:
    rows = [[stop["id"], stop["row"], stop["expected_ripe"], stop["leg_distance"]] for stop in harvest["stops"]]
    return (_table(["plant (in visiting order)", "row", "expected ripe", "leg distance, m"], rows)
            + f"<p>Back to the workstation {_fmt(harvest['return_distance'])} m; total {_fmt(harvest['total_distance'])} m "
            f"({html.escape(harvest['distance'])}); expected ripe yield {harvest['total_expected_ripe']}.</p>")


def build_report(run_dir: Path) -> str:
    run_dir = Path(run_dir)
    rundir.read_config(run_dir)  # a run directory at all
    for name in REQUIRED:
        if not (run_dir / name).is_file():
            raise UserError(f"{run_dir}: missing {name} (run `renderloop {STAGE_OF[name]}` first)")
    config = (run_dir / "config.yaml").read_text(encoding="utf-8")
    scores = _read_json(run_dir / "detection_scores.json")
    counts = _read_json(run_dir / "counts.json")
    harvest = _read_json(run_dir / "harvest.json")
    timings = _read_json(run_dir / TIMINGS) if (run_dir / TIMINGS).is_file() else {}
    row_plots = sorted((run_dir / "counts").glob("row_*.png"), key=lambda p: int(p.stem.split("_")[1]))
    try:
        sections = [
            f"<h1>renderloop run: {html.escape(run_dir.name)}</h1>",
            "<h2>Yield</h2>" + _counts_section(counts),
            "<h2>Greenhouse</h2>" + _image(run_dir / "scene_topview.png", "top view"),
            "<h2>Scan flight</h2><div class='figures'>" + _image(run_dir / "flight_paths.png", "planned and flown paths")
            + _image(run_dir / "tracking_error.png", "tracking error") + "</div>",
            "<h2>Frames</h2>" + _image(run_dir / "contact_sheet.png", "contact sheet"),
            "<h2>Detections</h2>" + _table(["figure", "value"], [[k, v] for k, v in scores.items()])
            + _image(run_dir / "detections.png", "detections (left) and truth (right)"),
            "<h2>Clusters per row</h2><div class='figures'>" + "".join(_image(p, p.stem) for p in row_plots) + "</div>",
            "<h2>Harvest plan</h2>" + _harvest_section(harvest),
            "<h2>Stage times</h2>" + (_table(["stage", "seconds"], [[s.name, timings.get(s.name)] for s in STAGES]) if timings
                                       else "<p>Not recorded (<code>renderloop run</code> writes them to timings.json).</p>"),
            "<h2>Config</h2><pre>" + html.escape(config) + "</pre>",
        ]
    except (KeyError, TypeError) as error:
        raise UserError(f"{run_dir}: counts.json or harvest.json lacks {error}") from None
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>renderloop report</title>"
            f"<style>{STYLE}</style></head><body>{''.join(sections)}</body></html>\n")


def write_report(run_dir: Path, out: Path | None = None) -> Path:
    out = Path(out) if out is not None else Path(run_dir) / "report.html"
    write_text(out, build_report(run_dir))
    return out
