"""`renderloop count DIR`: count the fruit per plant and per row from detections.json; plan the harvest.

Reads `config.yaml`, `scene.json` (layout and truth), `groundtruth.txt` (how many
frames were flown) and `detections.json`; writes one clustering plot per row in
`counts/row_<id>.png`, then `harvest.json` (see `renderloop.counting.harvest`) and
`counts.json` last: the settings it records
(counting config and seed) mark the stage done, so changing them, or --no-layout,
redoes it even when no input changed.

`detections.json` (written by `renderloop detect`)::

    {"model": str, "score_threshold": float in [0, 1],
     "windows": ["2x2", ...] (optional: window layouts searched; older files say "grid": int >= 1, windows per side),
     "mirror": bool (optional: the mirrored frame searched too),
     "depth": str (optional: "depth" or "depth_sensor"),
     "frames": [{"index": int >= 0, "timestamp": float, "image": "rgb/000000.png",
                 "detections": [{"bbox": [x0, y0, x1, y1] (pixels, x0 <= x1, y0 <= y1),
                                 "score": float in [0, 1], "label": "ripe" | "unripe",
                                 "position": [x, y, z] (world frame, m) | null (no depth)}]}]}

It is read strictly (unknown keys, wrong types, NaN or infinite numbers are errors),
every `image` must exist in the run directory and every `index` must be a frame of
groundtruth.txt, so counts are never made from another run's detections.

`counts.json`::

    {"plants": [{"id", "row", "estimate", "truth", "unripe_estimate", "unripe_truth",
                 "clusters": [[x, y, z], ...] (ripe), "unripe_clusters": [[x, y, z], ...]}],
     "rows": [{"id", "estimate", "truth", "unripe_estimate", "unripe_truth",
               "detections": n_init (ripe points of the row after false-positive removal),
               "unripe_detections", "removed", "unripe_removed" (false positives dropped)}],
     "total": {"estimate", "truth", "error_pct" (100 (estimate - truth) / truth, null if truth is 0),
               "unripe_estimate", "unripe_truth", "exact_plants" (fraction of all plants counted exactly)},
     "detections": {"frames", "ripe", "unripe" (detections with a position), "no_position",
                    "removed", "unripe_removed" (false positives dropped, all rows)},
     "settings": the counting config used (with the effective use_layout) and the seed}

`estimate` is always the ripe count: ripe fruit are what the harvest plan is for.
Points are in metres, world frame, rounded to the micrometre so that the same inputs
and seed give the same bytes.
"""

from __future__ import annotations

import json
from pathlib import Path, PurePosixPath
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from renderloop.config import Config, CountingConfig
from renderloop.counting.cluster import CLASSES, RowCount, count_rows
from renderloop.counting.harvest import plan_harvest
from renderloop.counting.plots import draw_row
from renderloop.errors import UserError, field_path
from renderloop.io import rundir
from renderloop.io.atomic import write_json
from renderloop.io.tum import read_tum
from renderloop.scene.model import Scene, load_scene

DETECTIONS = "detections.json"
INPUTS = ("config.yaml", "scene.json", "groundtruth.txt", DETECTIONS)
OUTPUTS = ("counts.json", "harvest.json")
PLOT_DIR = "counts"
DIGITS = 6  # metres to the micrometre: stable bytes, far below any noise

Finite = Annotated[float, Field(allow_inf_nan=False)]
Unit = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


class Detection(_Strict):
    bbox: tuple[Finite, Finite, Finite, Finite]
    score: Unit
    label: Literal["ripe", "unripe"]
    position: tuple[Finite, Finite, Finite] | None

    @model_validator(mode="after")
    def _ordered_box(self) -> Detection:
        x0, y0, x1, y1 = self.bbox
        if x1 < x0 or y1 < y0:
            raise ValueError(f"bbox {list(self.bbox)} is not [x0, y0, x1, y1] with x0 <= x1 and y0 <= y1")
        return self


class Frame(_Strict):
    index: Annotated[int, Field(ge=0)]
    timestamp: Finite
    image: str
    detections: list[Detection]


class Detections(_Strict):
    model: str
    score_threshold: Unit
    windows: list[str] = []  # window layouts (columns x rows) searched besides the whole frame; informational
    grid: int | None = Field(None, ge=1)  # what files written before the layouts said instead: windows per side
    mirror: bool = False  # whether the detector also searched the mirrored frame; informational
    depth: str | None = None  # which depth images gave the positions; informational
    frames: list[Frame]


def plot_path(row_id: int) -> str:
    return f"{PLOT_DIR}/row_{row_id}.png"


def read_detections(run_dir: Path, frame_count: int) -> Detections:
    """Parse and check `detections.json` against the run directory; any problem is a one-line UserError."""
    path = Path(run_dir) / DETECTIONS
    try:
        data = Detections.model_validate_json(path.read_bytes())
    except ValidationError as exc:
        error = exc.errors()[0]
        field = field_path(error["loc"])
        message = error["msg"].removeprefix("Value error, ")
        if error["type"] == "extra_forbidden":
            message = "unknown field"
        raise UserError(f"{path}: {field + ': ' if field else ''}{message}") from None
    seen: set[int] = set()
    for number, frame in enumerate(data.frames):
        where = f"{path}: frames.{number}"
        if frame.index >= frame_count:
            raise UserError(f"{where}: index {frame.index} but groundtruth.txt has {frame_count} frames")
        if frame.index in seen:
            raise UserError(f"{where}: frame index {frame.index} appears twice")
        seen.add(frame.index)
        image = PurePosixPath(frame.image)
        if image.is_absolute() or ".." in image.parts or not (Path(run_dir) / image).is_file():
            raise UserError(f"{where}: image {frame.image!r} is not a file of {run_dir}")
    return data


def class_points(detections: Detections) -> dict[str, np.ndarray]:
    """World points of each class; detections without depth have no place to count."""
    points: dict[str, list] = {label: [] for label in CLASSES}
    for frame in detections.frames:
        for detection in frame.detections:
            if detection.position is not None:
                points[detection.label].append(detection.position)
    return {label: np.array(found, dtype=float).reshape(-1, 3) for label, found in points.items()}


def _rounded(points: np.ndarray) -> list[list[float]]:
    return [[round(float(v), DIGITS) for v in point] for point in points]


def _truth(scene: Scene) -> dict[int, dict[str, int]]:
    truth = {plant.id: {label: 0 for label in CLASSES} for plant in scene.plants}
    for pepper in scene.peppers:
        truth[pepper.plant]["ripe" if pepper.ripe else "unripe"] += 1
    return truth


def _error_pct(estimate: int, truth: int) -> float | None:
    return None if truth == 0 else round(100.0 * (estimate - truth) / truth, 4)


def summarise(scene: Scene, counts: dict[str, list[RowCount]], detections: Detections, settings: dict) -> dict:
    """The `counts.json` document from the per-row clusterings of both classes."""
    truth = _truth(scene)
    centers = {plant.id: {label: [] for label in CLASSES} for plant in scene.plants}
    for label, rows in counts.items():
        for row in rows:
            for plant_id, center in zip(row.plants, row.clusters.centers):
                centers[int(plant_id)][label].append(center)
    plants = [{
        "id": plant.id, "row": plant.row,
        "estimate": len(centers[plant.id]["ripe"]), "truth": truth[plant.id]["ripe"],
        "unripe_estimate": len(centers[plant.id]["unripe"]), "unripe_truth": truth[plant.id]["unripe"],
        "clusters": _rounded(np.array(centers[plant.id]["ripe"]).reshape(-1, 3)),
        "unripe_clusters": _rounded(np.array(centers[plant.id]["unripe"]).reshape(-1, 3)),
    } for plant in scene.plants]
    by_row = {label: {row.row: row for row in rows} for label, rows in counts.items()}
    rows = []
    for row in scene.rows:
        mine = [plant for plant in plants if plant["row"] == row.id]
        rows.append({
            "id": row.id,
            **{key: sum(plant[key] for plant in mine) for key in ("estimate", "truth", "unripe_estimate", "unripe_truth")},
            "detections": by_row["ripe"][row.id].clusters.n_init,
            "unripe_detections": by_row["unripe"][row.id].clusters.n_init,
            "removed": len(by_row["ripe"][row.id].removed),
            "unripe_removed": len(by_row["unripe"][row.id].removed),
        })
    total = {key: sum(plant[key] for plant in plants) for key in ("estimate", "truth", "unripe_estimate", "unripe_truth")}
    total["error_pct"] = _error_pct(total["estimate"], total["truth"])
    total["exact_plants"] = round(sum(p["estimate"] == p["truth"] for p in plants) / len(plants), DIGITS) if plants else None
    every = [d for frame in detections.frames for d in frame.detections]
    placed = {label: sum(1 for d in every if d.label == label and d.position is not None) for label in CLASSES}
    return {
        "plants": plants,
        "rows": rows,
        "total": total,
        "detections": {"frames": len(detections.frames), **placed,
                       "no_position": sum(1 for d in every if d.position is None),
                       "removed": sum(row["removed"] for row in rows),
                       "unripe_removed": sum(row["unripe_removed"] for row in rows)},
        "settings": settings,
    }


def settings_of(counting: CountingConfig, seed: int) -> dict:
    return {**counting.model_dump(mode="json"), "seed": seed}


def read_counts(run_dir: Path) -> dict:
    """The `counts.json` of a run directory, as written by run_count."""
    path = Path(run_dir) / "counts.json"
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{run_dir}: no counts.json (run `renderloop count` first)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UserError(f"{path}: not a readable JSON file ({exc.__class__.__name__})") from None


def _recorded_settings(run_dir: Path) -> dict | None:
    """The settings counts.json was made with; None when there is no readable record (then it is redone)."""
    try:
        recorded = read_counts(run_dir)
    except UserError:
        return None
    return recorded.get("settings") if isinstance(recorded, dict) else None


def run_count(run_dir: Path, config: Config, force: bool = False, use_layout: bool | None = None) -> bool:
    """Count and plan; False when counts.json, harvest.json and the row plots are already
    complete for these inputs and these counting settings (`use_layout` None keeps the config's)."""
    run_dir = Path(run_dir)
    rundir.require(run_dir, ("config.yaml", "scene.json"), "scene")
    rundir.require(run_dir, ("groundtruth.txt",), "fly")
    if not (run_dir / DETECTIONS).is_file():
        raise UserError(f"{run_dir}: no {DETECTIONS} (run `renderloop detect` first)")
    counting = config.counting if use_layout is None else config.counting.model_copy(update={"use_layout": use_layout})
    settings = settings_of(counting, config.seed)
    scene = load_scene(run_dir / "scene.json")
    outputs = (*OUTPUTS, *(plot_path(row.id) for row in scene.rows))
    if not force and rundir.complete(run_dir, outputs, INPUTS) and _recorded_settings(run_dir) == settings:
        return False

    times, _, _ = read_tum(run_dir / "groundtruth.txt")
    detections = read_detections(run_dir, len(times))
    points = class_points(detections)
    counts = {label: count_rows(scene, points[label], label, counting, config.seed) for label in CLASSES}
    document = summarise(scene, counts, detections, settings)

    (run_dir / PLOT_DIR).mkdir(exist_ok=True)
    truth = _truth(scene)
    for index, row in enumerate(scene.rows):
        draw_row(scene, [counts[label][index] for label in CLASSES], truth, run_dir / plot_path(row.id))
    estimates = {plant["id"]: plant["estimate"] for plant in document["plants"]}
    write_json(run_dir / "harvest.json", plan_harvest(scene, estimates, counting.harvest_min_ripe))
    write_json(run_dir / "counts.json", document)  # last: its settings record marks the stage done
    return True
