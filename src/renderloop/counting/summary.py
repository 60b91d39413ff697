"""The `counts.json` document of a count: per plant, per row and in total, the estimates against the truth.

Points are in metres, world frame, rounded to the micrometre so that the same inputs
and seed give the same bytes.

A scan of some rows (`planner.row`) is counted and scored against those rows alone
(`Scene.of_rows`): their plants, their fruit and the detections whose points belong to
them, so the rows it never visited do not show as missed fruit. The compartment's count
is then the merge of its rows' missions (`renderloop.counting.merge`).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from renderloop.config import Config, CountingConfig
from renderloop.counting.assign import NO_PLANT, rows_of_points
from renderloop.counting.cluster import CLASSES, RowCount, class_points, count_rows
from renderloop.counting.harvest import plan_harvest
from renderloop.counting.uncertainty import (
    LABEL,
    CountUncertainty,
    Uncertainty,
    credit_of,
    lone_detections,
    stored_distribution,
    uncertainty,
)
from renderloop.counting.visibility import Seen
from renderloop.rundir.models import Counts, Detections, Harvest
from renderloop.scene.model import Scene

DIGITS = 6  # metres to the micrometre: stable bytes, far below any noise
SUMMED = ("estimate", "truth", "unripe_estimate", "unripe_truth")  # a row's and the total's, its plants' added up


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


def total_of(plants: Sequence[Mapping[str, Any]], interval: Mapping[str, Any] | None, misses: bool) -> dict[str, Any]:
    """counts.json's `total` from its plant entries: their sums, the error, the share of plants counted exactly;
    `interval` is the total's (None: counted without the intervals), and `misses` says the plants' `unseen` and
    `too_small` are known, which adds the scan's misses and the error against the fruit it showed."""
    total: dict[str, Any] = {key: sum(plant[key] for plant in plants) for key in SUMMED}
    total["error_pct"] = _error_pct(total["estimate"], total["truth"])
    total["exact_plants"] = round(sum(p["estimate"] == p["truth"] for p in plants) / len(plants), DIGITS) if plants else None
    total["interval"] = None if interval is None else dict(interval)
    if misses:
        total["unseen"] = sum(p["unseen"] for p in plants)
        total["too_small"] = sum(p["too_small"] for p in plants)
        total["seen_error_pct"] = _error_pct(total["estimate"], total["truth"] - total["unseen"] - total["too_small"])
    return total


def summarise(scene: Scene, counts: dict[str, list[RowCount]], detections: Detections, settings: dict,
              seen: dict[int, Seen] | None = None, uncertain: Uncertainty | None = None,
              unripe_lone: Mapping[int, Sequence[np.ndarray]] | None = None, unripe_lone_credit: float = 0.0) -> Counts:
    """The `counts.json` document from the per-row clusterings of both classes; with `uncertain`, the ripe counts'
    estimates (clusters and the credit of lone detections), intervals and each row's distribution
    (`renderloop.counting.uncertainty`), which must have been made from the same ripe rows; with `unripe_lone` (per
    plant, its lone green detections, `lone_detections` of the green rows) each plant's green estimate adds
    `unripe_lone_credit` of a fruit for each, rounded half up. It scores against every row of `scene` and tallies every
    detection of `detections`: a scan of some rows passes the scene and the detections of those rows (`count_scan`)."""
    truth, misses = truth_counts(scene), _scan_misses(scene, seen)
    intervals = _plant_uncertainty(scene, uncertain)
    green_lone = {plant.id: list((unripe_lone or {}).get(plant.id, ())) for plant in scene.plants}
    centers = {plant.id: {label: [] for label in CLASSES} for plant in scene.plants}
    for label, rows in counts.items():
        for row in rows:
            for plant_id, center in zip(row.plants, row.clusters.centers):
                centers[int(plant_id)][label].append(center)
    plants = [{
        "id": plant.id, "row": plant.row,
        "estimate": len(centers[plant.id]["ripe"]) if uncertain is None else uncertain.plants[plant.id].estimate,
        "truth": truth[plant.id]["ripe"],
        "unripe_estimate": len(centers[plant.id]["unripe"]) + credit_of(len(green_lone[plant.id]), unripe_lone_credit),
        "unripe_truth": truth[plant.id]["unripe"],
        "clusters": _rounded(np.array(centers[plant.id]["ripe"]).reshape(-1, 3)),
        "unripe_clusters": _rounded(np.array(centers[plant.id]["unripe"]).reshape(-1, 3)),
        "seen_once": [] if uncertain is None else _rounded(uncertain.plants[plant.id].lone_points),
        "unripe_seen_once": _rounded(np.array(green_lone[plant.id]).reshape(-1, 3)),
        **misses[plant.id],
        **intervals[plant.id],
    } for plant in scene.plants]
    by_row = {label: {row.row: row for row in rows} for label, rows in counts.items()}
    rows = []
    for row in scene.rows:
        mine = [plant for plant in plants if plant["row"] == row.id]
        rows.append({
            "id": row.id,
            **{key: sum(plant[key] for plant in mine) for key in SUMMED},
            "detections": by_row["ripe"][row.id].clusters.n_init,
            "unripe_detections": by_row["unripe"][row.id].clusters.n_init,
            "removed": len(by_row["ripe"][row.id].removed),
            "unripe_removed": len(by_row["unripe"][row.id].removed),
            "interval": None if uncertain is None else _interval(uncertain.rows[row.id]),
            "distribution": None if uncertain is None else stored_distribution(uncertain.rows[row.id].pmf),
        })
    total = total_of(plants, None if uncertain is None else _interval(uncertain.total), seen is not None)
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


def scanned_rows(config: Config) -> list[int] | None:
    """The rows a run's scan visited and its count is of (`planner.row`); None: every row."""
    return None if config.planner.row is None else [config.planner.row]


def scanned_detections(scene: Scene, detections: Detections, rows: Collection[int], counting: CountingConfig) -> Detections:
    """`detections` less those whose points `count_rows` would count in a row of `scene` not in `rows` (a neighbouring
    row's fruit seen past the scanned one): counted against `scene.of_rows(rows)` they are what counting the whole
    scene gives those rows. Every frame stays, and so do the detections without a position (the scan's, not a row's)."""
    rows = {int(row) for row in rows}
    placed = [d.position for frame in detections.frames for d in frame.detections if d.position is not None]
    counted, nearest = rows_of_points(scene, np.array(placed, dtype=float), counting.use_layout, counting.volume_margin)
    kept = iter(np.isin(np.where(counted == NO_PLANT, nearest, counted), list(rows)))  # a false positive: its table's
    frames = [frame.model_copy(update={"detections": [d for d in frame.detections if d.position is None or next(kept)]})
              for frame in detections.frames]
    return detections.model_copy(update={"frames": frames})


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
    """A scan counted: each class's count per row (in the order of `scene`'s rows), the counts document, the harvest
    plan and the scene they are of (the scanned rows', `Scene.of_rows`)."""

    rows: dict[str, list[RowCount]]
    counts: Counts
    harvest: Harvest
    scene: Scene


def count_scan(scene: Scene, detections: Detections, poses: np.ndarray, counting: CountingConfig, seed: int,
               seen: dict[int, Seen] | None, rows: Collection[int] | None = None) -> ScanCount:
    """Count the fruit of `detections` per row, plant and class, with each plant's interval and the harvest plan; `poses`
    are the scan's camera poses (T_world_optical), one per frame, `seen` how the scan saw each fruit (None: not
    known) and `rows` the rows it scanned (None: every row), which alone it counts, scores and plans the harvest of
    (`scanned_detections`); a row the scene lacks is refused in one line."""
    if rows is not None and (scanned := scene.of_rows(rows)) is not scene:
        detections, scene = scanned_detections(scene, detections, rows, counting), scanned
    points = class_points(detections.frames, counting.eps)
    counted = {label: count_rows(scene, points[label], label, counting, seed) for label in CLASSES}
    cameras = {index: pose[:3, 3] for index, pose in enumerate(poses)}
    uncertain = uncertainty(scene, detections.frames, cameras, counting, seed, estimate=counted[LABEL])
    document = summarise(scene, counted, detections, settings_of(counting, seed), seen, uncertain,
                         lone_detections(scene, counted["unripe"], counting), counting.unripe_lone_credit)
    estimates = {plant.id: plant.estimate for plant in document.plants}
    harvest = Harvest.model_validate(plan_harvest(scene, estimates, counting.harvest_min_ripe), strict=False)
    return ScanCount(counted, document, harvest, scene)
