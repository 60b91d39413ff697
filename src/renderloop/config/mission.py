"""How the scan is flown (`mission`)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from renderloop.config.fields import MAX_CAMERA_RATE_HZ, Count, Fraction, Real, Strict
from renderloop.config.perception import IntervalConfig


class AdaptiveConfig(Strict):
    """The adaptive mission: a coarse pass over every plant, then re-scans of the plants whose count is uncertain."""

    first_pass_rate_hz: Real(0.01, MAX_CAMERA_RATE_HZ) = Field(
        0.5, description="Camera rate of the coarse first pass (the static scan's path), Hz.")
    views_per_round: Count(1, 50) = Field(3, description="Most views added to one plant in one re-scan.")
    rounds: Count(1, 10) = Field(2, description="Most re-scans of one plant.")
    budget_s: Real(0.0, 3600.0) = Field(
        20.0, description="Flight time the re-scans of one plant may add, s; 0 flies the first pass only.")
    voxel: Real(0.005, 0.2) = Field(0.02, description="Edge of a cell of the voxel map built from the depth frames, m.")
    min_gain: Count(0, 1_000_000) = Field(
        20, description="Unknown cells of the canopy a view must newly see to be worth flying to (an uncertain fruit "
        "it sees counts as a whole canopy's worth).")
    interval: IntervalConfig | None = Field(
        None, description="The interval of the count of an adaptive run (counts.json), fitted on adaptive runs: their "
        "counts rest on views chosen where the first pass was unsure. None: counting.interval. The mission's own "
        "decisions always use counting.interval: they are taken on a scan as sparse as the first pass.")
    lone_credit: Fraction | None = Field(
        None, description="counting.lone_credit of an adaptive run's count (counts.json), fitted on adaptive runs; "
        "None: counting.lone_credit. The mission's own decisions use counting.lone_credit.")


class MissionConfig(Strict):
    """How the scan is flown."""

    kind: Literal["static", "adaptive"] = Field(
        "static", description="static: the planned scan at the camera's rate. adaptive: a coarse first pass at "
        "mission.adaptive.first_pass_rate_hz, then re-scans of uncertain plants from next-best views (always online).")
    online: bool = Field(False, description="Render and detect while flying (the simulation steps, the camera renders "
                         "at its instants, perception runs on each frame as it arrives); same files and counts as the "
                         "batch stages fly, render, detect.")
    adaptive: AdaptiveConfig = Field(AdaptiveConfig(), description="The adaptive mission's settings.")
    split: Literal["none", "rows"] = Field(
        "none", description="none: one mission scans every row (or planner.row). rows: one mission a row, each a run "
        "of its own in rows/row_<id> and a task of the executor, counted together into the compartment's counts.json "
        "and harvest.json.")
    uavs: Count(1, 64) = Field(
        1, description="UAVs sharing the missions of a split scan (fleet.json says which flies which row when): each "
        "flies one mission at a time, and no two fly in one aisle at once. More than 1 needs split: rows.")
