"""The JSON files of a run directory as pydantic models: what each holds, in SI units.

Files are read strictly (unknown keys, wrong types, NaN or infinite numbers are
errors) and every number is bounded (the bounds below, which the run's tables share),
so a damaged or hand-edited file fails in one line naming the file and the field
(`renderloop.rundir.files.read_model`) instead of deep inside a stage. The scene
(`scene.json`) has its own model in `renderloop.scene.model`.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, RootModel, model_validator

from renderloop.config.fields import MAX_PLANTS, MAX_TABLES, WORLD_BOUND
from renderloop.config.perception import MAX_ENLARGEMENT
from renderloop.io.images import MAX_PIXELS

# About 16 weeks: longer than any scan the config allows (the planner's slowest limits over the largest floor take
# days), short enough that a time keeps its microseconds in a float64. Stage timings (wall-clock) share it.
MAX_TIME = 1e7  # s
# No two points within WORLD_BOUND of the origin on every axis are farther apart.
MAX_DISTANCE = 2 * math.sqrt(3) * WORLD_BOUND  # m
# A route visits each plant once: its legs add up to at most one MAX_DISTANCE per plant and one back.
MAX_ROUTE = (MAX_PLANTS + 1) * MAX_DISTANCE  # m
# Counts of fruit, frames and detections: far above what a run holds, small enough for every integer array.
MAX_COUNT = 2**31 - 1

Unit = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]
Count = Annotated[int, Field(ge=0, le=MAX_COUNT)]
Time = Annotated[float, Field(ge=0, le=MAX_TIME, allow_inf_nan=False)]  # simulation or wall-clock seconds
Distance = Annotated[float, Field(ge=0, le=MAX_DISTANCE, allow_inf_nan=False)]  # m
RouteLength = Annotated[float, Field(ge=0, le=MAX_ROUTE, allow_inf_nan=False)]  # m, legs added up
Coordinate = Annotated[float, Field(ge=-WORLD_BOUND, le=WORLD_BOUND, allow_inf_nan=False)]  # m, world frame
Point = tuple[Coordinate, Coordinate, Coordinate]
Pixel = Annotated[float, Field(ge=0, le=MAX_PIXELS, allow_inf_nan=False)]  # no image side is longer
Angle = Annotated[float, Field(ge=-2 * math.pi, le=2 * math.pi, allow_inf_nan=False)]  # rad
Percent = Annotated[float, Field(ge=-100, le=100 * MAX_COUNT, allow_inf_nan=False)]  # 100 (estimate - x) / x, estimate >= 0
PlantId = Annotated[int, Field(ge=0, lt=MAX_PLANTS)]
RowId = Annotated[int, Field(ge=0, lt=MAX_TABLES)]
Seed = Annotated[int, Field(ge=0, le=2**63 - 1)]


class FileModel(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


class Detection(FileModel):
    """One box: pixels with exclusive far edges; `position` is the fruit point in the world frame, m (null: no depth)."""

    bbox: tuple[Pixel, Pixel, Pixel, Pixel]
    score: Unit
    label: Literal["ripe", "unripe"]
    position: Point | None

    @model_validator(mode="after")
    def _ordered_box(self) -> Detection:
        x0, y0, x1, y1 = self.bbox
        if x1 < x0 or y1 < y0:
            raise ValueError(f"bbox {list(self.bbox)} is not [x0, y0, x1, y1] with x0 <= x1 and y0 <= y1")
        return self


class DetectionFrame(FileModel):
    index: Count  # the frame's line in groundtruth.txt
    timestamp: Time  # simulation seconds
    image: str  # the RGB image, relative to the run directory
    detections: list[Detection]


class Detections(FileModel):
    """`detections.json`: the detector's settings and every frame's boxes (`renderloop detect`)."""

    model: str
    score_threshold: Unit
    windows: list[str] = []  # window layouts (columns x rows) searched besides the whole frame
    mirror: bool = False  # the mirrored frame searched too
    # the most a window may be enlarged for its layout to be searched (detector.max_window_enlargement)
    max_window_enlargement: Annotated[float, Field(ge=1, le=16, allow_inf_nan=False)] = MAX_ENLARGEMENT
    depth: str | None = None  # which depth stream gave the positions
    frames: list[DetectionFrame]


class DetectionScores(FileModel):
    """`detection_scores.json`: the detections scored against the masks (the simulator's truth)."""

    ripe_findable: Count
    ripe_found: Count
    ripe_recall: Unit | None
    detections_scored: Count
    false_detections: Count
    false_rate: Unit | None
    label_accuracy: Unit | None
    position_error_median_m: Distance | None
    position_error_p90_m: Distance | None


class CountInterval(FileModel):
    """The ripe count's interval: the true count lies in [low, high] with probability `level` under the counting's
    model of its uncertainty (renderloop.counting.uncertainty)."""

    low: Count
    high: Count
    level: Unit

    @model_validator(mode="after")
    def _ordered(self) -> CountInterval:
        if self.low > self.high:
            raise ValueError(f"low {self.low} is larger than high {self.high}")
        return self


class PlantCount(FileModel):
    id: PlantId
    row: RowId
    estimate: Count  # ripe fruit counted: the clusters, and counting.lone_credit of a fruit for each seen once
    truth: Count  # ripe fruit in the scene
    unripe_estimate: Count  # green fruit counted: the clusters, and counting.unripe_lone_credit of a fruit for each seen once
    unripe_truth: Count
    clusters: list[Point]  # counted ripe fruit, world frame, m
    unripe_clusters: list[Point]
    seen_once: list[Point] = []  # ripe detections in no cluster, away from every counted fruit (fruit seen once), m
    unripe_seen_once: list[Point] = []  # the same of the green detections, m
    unseen: Count | None = None  # ripe fruit of the plant no frame showed (from the masks; null without masks)
    too_small: Count | None = None  # ripe fruit only ever seen smaller than the detector's findable size
    interval: CountInterval | None = None  # where the true ripe count lies (null: counted without the intervals)
    weak_clusters: Count | None = None  # counted ripe fruit whose cluster is weakly supported or seen from one side
    unseen_fraction: Unit | None = None  # share of the canopy box no depth frame has seen (null: not known)


class RowCount(FileModel):
    id: RowId
    estimate: Count
    truth: Count
    unripe_estimate: Count  # green fruit counted: the clusters, and counting.unripe_lone_credit of a fruit for each seen once
    unripe_truth: Count
    detections: Count  # ripe points of the row after false-positive removal (the paper's n_init)
    unripe_detections: Count
    removed: Count  # false positives dropped
    unripe_removed: Count
    interval: CountInterval | None = None  # where the row's true ripe count lies: its plants' distributions convolved
    # cut where less than 1e-12 is left (counting.uncertainty.stored_distribution); merged rows add up by it
    distribution: list[Unit] | None = None  # P(the row's true ripe count = k), k = 0, 1, ...; null: without the intervals


class TotalCount(FileModel):
    estimate: Count
    truth: Count
    error_pct: Percent | None  # 100 (estimate - truth) / truth; null when there is no ripe fruit
    unripe_estimate: Count  # green fruit counted: the clusters, and counting.unripe_lone_credit of a fruit for each seen once
    unripe_truth: Count
    exact_plants: Unit | None  # share of plants counted exactly
    unseen: Count | None = None  # ripe fruit no frame showed: the scan's misses, not the detector's
    too_small: Count | None = None  # ripe fruit seen, but never at the detector's findable size
    seen_error_pct: Percent | None = None  # 100 (estimate - seen) / seen, seen = truth - unseen - too_small
    interval: CountInterval | None = None  # where the true ripe total lies: the rows' distributions convolved


class DetectionTally(FileModel):
    frames: Count
    ripe: Count  # detections with a position
    unripe: Count
    no_position: Count
    removed: Count
    unripe_removed: Count


class Counts(FileModel):
    """`counts.json`: per plant, per row and in total, estimate beside truth (`renderloop count`).
    `estimate` is always the ripe count: ripe fruit are what the harvest plan is for."""

    plants: list[PlantCount]
    rows: list[RowCount]
    total: TotalCount
    detections: DetectionTally
    settings: dict[str, Any]  # the counting config used (with the effective use_layout) and the seed


class HarvestStop(FileModel):
    id: PlantId
    row: RowId
    expected_ripe: Count
    position: Point
    leg_distance: Distance  # m, from the previous stop or the workstation


class Harvest(FileModel):
    """`harvest.json`: the plants worth bringing to the workstation, in visiting order (`renderloop count`)."""

    workstation: Point
    distance: str  # how distances are measured
    min_ripe: Count
    stops: list[HarvestStop]
    return_distance: Distance
    total_distance: RouteLength
    total_expected_ripe: Count


class Timings(RootModel[dict[str, Time]]):
    """`timings.json`: seconds of the last run of each stage (`renderloop run`)."""


class RenderRecord(FileModel):
    """`render.json`: what the frames of the run directory were rendered from; another record means other frames."""

    model_config = ConfigDict(extra="forbid", frozen=True)  # not strict: the camera and renderer are plain JSON
    backend: str
    frames: Count
    poses_sha256: str
    scene_sha256: str
    seed: Seed
    camera: dict[str, Any]
    renderer: dict[str, Any]


class Estimate(FileModel):
    """A plant's ripe count as the mission saw it at a decision: the estimate and its interval."""

    estimate: Count
    low: Count
    high: Count
    weak: Count  # counted fruit whose cluster is weakly supported
    unseen: Unit | None  # share of the canopy box no depth frame has seen
    seen_once: Count = 0  # lone detections: fruit seen once, not counted


class MissionView(FileModel):
    """A view flown to: where about the plant (viewpoints.View), when, and what it was expected to show."""

    azimuth: Angle  # rad, counter-clockwise from world +x, about the plant's axis
    height: Coordinate  # m above the canopy's middle
    distance: Distance  # m, camera to the plant's axis, horizontally
    time: Time  # simulation s when the camera was asked for the frame
    frame: Count | None  # its frame's index; null when the mission ended before it was taken
    unknown_cells: Count  # cells of the canopy it was expected to see for the first time
    uncertain_fruit: Count  # weakly supported fruit it was expected to see


class MissionRound(FileModel):
    decided_at: Time  # simulation s
    why: str
    before: Estimate
    after: Estimate | None  # null when the mission ended before the round's frames were in
    views: list[MissionView]


class MissionPlant(FileModel):
    id: PlantId
    row: RowId
    first_pass: Estimate
    final: Estimate
    rounds: list[MissionRound]
    fallback: str | None  # why the plant kept the first pass alone (no reachable view, no budget, ...)


class HarvestUpdate(FileModel):
    """The harvest plan as it stood after a decision: from the ripe estimates of the plants counted so far."""

    time: Time  # simulation s of the decision
    row: RowId  # the row just decided
    round: Count  # 0: after the row's first pass; n: after its n-th round of added views
    plants_counted: Count  # plants whose row has been decided at least once
    stops: list[PlantId]  # plant ids in visiting order (harvest.json's rule)
    expected_ripe: Count
    total_distance: RouteLength  # m


class Mission(FileModel):
    """`mission.json`: what the adaptive mission decided, plant by plant (`renderloop run --mission adaptive`)."""

    kind: Literal["adaptive"]
    settings: dict[str, Any]  # the mission config
    frames: Count  # frames rendered in all
    first_pass_frames: Count
    flight_time_s: Time  # s, the whole mission (the hover at its end not included)
    plants: list[MissionPlant]
    harvest: list[HarvestUpdate] = []  # the plan after each decision, as the counts settled


class Flight(FileModel):
    """One UAV's mission of one row, in simulated seconds from the compartment's start."""

    uav: Count  # index of the UAV, from 0
    row: RowId
    start_s: Time  # simulation s
    end_s: Time


class Schedule(FileModel):
    """`fleet.json`: which UAV flies which row's mission when (`renderloop.fleet.schedule`), and when the last ends."""

    uavs: Count  # UAVs shared the missions (some may fly none)
    flights: list[Flight]  # in the order the missions were given
    makespan_s: Time

    @model_validator(mode="after")
    def _consistent(self) -> Schedule:
        for number, flight in enumerate(self.flights):
            if flight.end_s < flight.start_s:
                raise ValueError(f"flights.{number}: ends at {flight.end_s} s, before it starts at {flight.start_s} s")
            if flight.uav >= self.uavs:
                raise ValueError(f"flights.{number}: uav {flight.uav} of {self.uavs} UAVs")
        rows = [flight.row for flight in self.flights]
        if len(set(rows)) != len(rows):
            raise ValueError("two flights of one row")
        if self.makespan_s != max((flight.end_s for flight in self.flights), default=0.0):
            raise ValueError(f"makespan_s {self.makespan_s} is not when the last flight ends")
        return self
