"""`renderloop count DIR`: count the fruit per plant and per row from detections.json; plan the harvest.

Reads `config.yaml`, `scene.json` (layout and truth), `groundtruth.txt` (how many
frames were flown, and where the camera was for each: the sides each fruit was seen
from, for the count's intervals) and `detections.json`; writes one clustering plot per row in
`counts/row_<id>.png`, then `harvest.json` (`renderloop.counting.harvest`) and
`counts.json` last (`renderloop.rundir.models.Counts`): the settings it records
(counting config and seed) mark the stage done, so changing them, or --no-layout,
redoes it even when no input changed.

Points are in metres, world frame, rounded to the micrometre so that the same inputs
and seed give the same bytes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderloop.config import Config, CountingConfig
from renderloop.counting.cluster import CLASSES, RowCount, class_points, count_rows
from renderloop.counting.harvest import plan_harvest
from renderloop.counting.plots import draw_row
from renderloop.counting.uncertainty import (
    LABEL,
    CountUncertainty,
    Uncertainty,
    uncertainty,
)
from renderloop.counting.visibility import Seen, fruit_visibility
from renderloop.errors import UserError
from renderloop.rundir import files, names
from renderloop.rundir.models import Counts, Detections, Harvest
from renderloop.rundir.stage import Job, Stage
from renderloop.scene.model import Scene

NEEDS = (names.CONFIG, names.SCENE, names.POSES, names.DETECTIONS)
DIGITS = 6  # metres to the micrometre: stable bytes, far below any noise


def _rounded(points: np.ndarray) -> list[list[float]]:
    return [[round(float(v), DIGITS) for v in point] for point in points]


def _truth(scene: Scene) -> dict[int, dict[str, int]]:
    truth = {plant.id: {label: 0 for label in CLASSES} for plant in scene.plants}
    for pepper in scene.peppers:
        truth[pepper.plant]["ripe" if pepper.ripe else "unripe"] += 1
    return truth


def _error_pct(estimate: int, truth: int) -> float | None:
    return None if truth == 0 else round(100.0 * (estimate - truth) / truth, 4)


def _scan_misses(scene: Scene, seen: dict[int, Seen] | None) -> dict[int, dict[str, int | None]]:
    """Per plant, ripe fruit no frame showed and ripe fruit never seen at a findable size (None without masks)."""
    misses: dict[int, dict[str, int | None]] = {plant.id: {"unseen": None, "too_small": None} for plant in scene.plants}
    if seen is None:
        return misses
    for plant in scene.plants:
        ripe = [p for p in scene.peppers_of(plant.id) if p.ripe]
        misses[plant.id] = {"unseen": sum(p.id not in seen for p in ripe),
                            "too_small": sum(p.id in seen and not seen[p.id].findable for p in ripe)}
    return misses


def _interval(count: CountUncertainty) -> dict:
    return {"low": count.low, "high": count.high, "level": count.level}


def _plant_uncertainty(scene: Scene, found: Uncertainty | None) -> dict[int, dict]:
    """Per plant, the interval, the weak clusters and the unseen fraction (None without an uncertainty)."""
    if found is None:
        return {plant.id: {"interval": None, "weak_clusters": None, "unseen_fraction": None} for plant in scene.plants}
    return {plant_id: {"interval": _interval(plant), "weak_clusters": len(plant.weak_centers),
                       "unseen_fraction": None if plant.unseen is None else round(plant.unseen, DIGITS)}
            for plant_id, plant in found.plants.items()}


def summarise(scene: Scene, counts: dict[str, list[RowCount]], detections: Detections, settings: dict,
              seen: dict[int, Seen] | None = None, uncertain: Uncertainty | None = None) -> Counts:
    """The `counts.json` document from the per-row clusterings of both classes; with `uncertain`, the ripe counts'
    estimates (clusters and the credit of lone detections) and intervals (`renderloop.counting.uncertainty`), which
    must have been made from the same ripe rows."""
    truth, misses = _truth(scene), _scan_misses(scene, seen)
    intervals = _plant_uncertainty(scene, uncertain)
    centers = {plant.id: {label: [] for label in CLASSES} for plant in scene.plants}
    for label, rows in counts.items():
        for row in rows:
            for plant_id, center in zip(row.plants, row.clusters.centers):
                centers[int(plant_id)][label].append(center)
    plants = [{
        "id": plant.id, "row": plant.row,
        "estimate": len(centers[plant.id]["ripe"]) if uncertain is None else uncertain.plants[plant.id].estimate,
        "truth": truth[plant.id]["ripe"],
        "unripe_estimate": len(centers[plant.id]["unripe"]), "unripe_truth": truth[plant.id]["unripe"],
        "clusters": _rounded(np.array(centers[plant.id]["ripe"]).reshape(-1, 3)),
        "unripe_clusters": _rounded(np.array(centers[plant.id]["unripe"]).reshape(-1, 3)),
        "seen_once": [] if uncertain is None else _rounded(uncertain.plants[plant.id].lone_points),
        **misses[plant.id],
        **intervals[plant.id],
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
            "interval": None if uncertain is None else _interval(uncertain.rows[row.id]),
        })
    total = {key: sum(plant[key] for plant in plants) for key in ("estimate", "truth", "unripe_estimate", "unripe_truth")}
    total["error_pct"] = _error_pct(total["estimate"], total["truth"])
    total["exact_plants"] = round(sum(p["estimate"] == p["truth"] for p in plants) / len(plants), DIGITS) if plants else None
    total["interval"] = None if uncertain is None else _interval(uncertain.total)
    if seen is not None:
        total["unseen"] = sum(p["unseen"] for p in plants)
        total["too_small"] = sum(p["too_small"] for p in plants)
        total["seen_error_pct"] = _error_pct(total["estimate"], total["truth"] - total["unseen"] - total["too_small"])
    every = [d for frame in detections.frames for d in frame.detections]
    placed = {label: sum(1 for d in every if d.label == label and d.position is not None) for label in CLASSES}
    return Counts.model_validate({
        "plants": plants,
        "rows": rows,
        "total": total,
        "detections": {"frames": len(detections.frames), **placed,
                       "no_position": sum(1 for d in every if d.position is None),
                       "removed": sum(row["removed"] for row in rows),
                       "unripe_removed": sum(row["unripe_removed"] for row in rows)},
        "settings": settings,
    }, strict=False)


def settings_of(counting: CountingConfig, seed: int) -> dict:
    return {**counting.model_dump(mode="json"), "seed": seed}


def run_counting(config: Config) -> CountingConfig:
    """The counting settings of a run's count: an adaptive run's interval and lone credit are
    `mission.adaptive.interval` and `.lone_credit` where set."""
    adaptive = config.mission.adaptive
    if config.mission.kind != "adaptive":
        return config.counting
    update = {name: value for name in ("interval", "lone_credit") if (value := getattr(adaptive, name)) is not None}
    return config.override({"counting": update}).counting


def _current(run_dir: Path, config: Config) -> bool:
    """counts.json was made with these counting settings, and every row's plot is there."""
    try:
        recorded = files.read_counts(run_dir)
        scene = files.read_scene(run_dir)
    except UserError:
        return False
    plots = all((run_dir / names.row_plot(row.id)).is_file() for row in scene.rows)
    return plots and recorded.settings == settings_of(run_counting(config), config.seed)


def _count(run_dir: Path, config: Config, job: Job) -> None:
    counting = run_counting(config)
    scene = files.read_scene(run_dir)
    times, poses = files.read_poses(run_dir)
    detections = files.read_detections(run_dir, len(times))
    points = class_points(detections.frames)
    counts = {label: count_rows(scene, points[label], label, counting, config.seed) for label in CLASSES}
    cameras = {index: pose[:3, 3] for index, pose in enumerate(poses)}
    uncertain = uncertainty(scene, detections.frames, cameras, counting, config.seed, estimate=counts[LABEL])
    document = summarise(scene, counts, detections, settings_of(counting, config.seed),
                         fruit_visibility(run_dir, len(times)), uncertain)

    truth = _truth(scene)
    for index, row in enumerate(scene.rows):
        path = run_dir / names.row_plot(row.id)
        path.parent.mkdir(exist_ok=True)
        draw_row(scene, [counts[label][index] for label in CLASSES], truth, path)
    estimates = {plant.id: plant.estimate for plant in document.plants}
    files.write_model(run_dir / names.HARVEST, Harvest.model_validate(plan_harvest(scene, estimates, counting.harvest_min_ripe), strict=False))
    files.write_model(run_dir / names.COUNTS, document)  # last: its settings record marks the stage done


STAGE = Stage("count", needs=NEEDS, work=_count, current=_current)
run_count = STAGE.run


def without_layout(config: Config) -> Config:
    """`renderloop count --no-layout`: nearest table and LocalOutlierFactor instead of the plant volumes."""
    return config.override({"counting": {"use_layout": False}})
