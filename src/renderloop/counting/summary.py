"""The `counts.json` document of a count: per plant, per row and in total, the estimates against the truth.

Points are in metres, world frame, rounded to the micrometre so that the same inputs
and seed give the same bytes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderloop.config import Config, CountingConfig
from renderloop.counting.cluster import CLASSES, RowCount, class_points, count_rows
from renderloop.counting.harvest import plan_harvest
from renderloop.counting.uncertainty import LABEL, CountUncertainty, Uncertainty, uncertainty
from renderloop.counting.visibility import Seen
from renderloop.rundir.models import Counts, Detections, Harvest
from renderloop.scene.model import Scene

DIGITS = 6  # metres to the micrometre: stable bytes, far below any noise


def _rounded(points: np.ndarray) -> list[list[float]]:
    return [[round(float(v), DIGITS) for v in point] for point in points]


def truth_counts(scene: Scene) -> dict[int, dict[str, int]]:
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
    truth, misses = truth_counts(scene), _scan_misses(scene, seen)
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


@dataclass(frozen=True)
class ScanCount:
    """A scan counted: each class's count per row (in the scene's row order), the counts document and the harvest plan."""

    rows: dict[str, list[RowCount]]
    counts: Counts
    harvest: Harvest


def count_scan(scene: Scene, detections: Detections, poses: np.ndarray, counting: CountingConfig, seed: int,
               seen: dict[int, Seen] | None) -> ScanCount:
    """Count the fruit of `detections` per row, plant and class, with each plant's interval and the harvest plan; `poses`
    are the scan's camera poses (T_world_optical), one per frame, and `seen` how the scan saw each fruit (None: not
    known)."""
    points = class_points(detections.frames)
    rows = {label: count_rows(scene, points[label], label, counting, seed) for label in CLASSES}
    cameras = {index: pose[:3, 3] for index, pose in enumerate(poses)}
    uncertain = uncertainty(scene, detections.frames, cameras, counting, seed, estimate=rows[LABEL])
    document = summarise(scene, rows, detections, settings_of(counting, seed), seen, uncertain)
    estimates = {plant.id: plant.estimate for plant in document.plants}
    harvest = Harvest.model_validate(plan_harvest(scene, estimates, counting.harvest_min_ripe), strict=False)
    return ScanCount(rows, document, harvest)
