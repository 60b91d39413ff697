"""Which UAV flies which row's mission, and when: list scheduling in simulated time.

A mission scans one row from the aisle(s) beside it; its corridor is the x-y box its scan occupies, the bounding
box of the scan's waypoints grown by the UAV's footprint radius. Transits (from the home position to the scan and
back, along the row ends) are not in the corridor: the row ends are the shared headland, where UAVs pass each
other, so only the scans are kept apart. The rules: a UAV flies one mission at a time, and two missions whose
corridors overlap (with positive area; boxes that only touch do not) never fly at the same time. Missions are
taken in the given order, each to the UAV that can start it earliest (ties to the lowest index), at the earliest
time the rules allow; a UAV takes its missions in that order too, never one in a gap before its last. The result
is deterministic and is written as `fleet.json` (`renderloop.rundir.models.Schedule`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from renderloop.config.fields import MAX_TABLES
from renderloop.errors import UserError
from renderloop.rundir.models import MAX_COUNT, MAX_TIME, Flight, Schedule


@dataclass(frozen=True)
class Box:
    """An axis-aligned x-y box, m, world frame."""

    x0: float
    y0: float
    x1: float
    y1: float

    def __post_init__(self) -> None:
        # A NaN edge would make every comparison false: a box overlapping nothing, missions flown together.
        if not all(map(math.isfinite, (self.x0, self.y0, self.x1, self.y1))) or self.x1 < self.x0 or self.y1 < self.y0:
            raise UserError(f"a corridor is a finite box with x0 <= x1 and y0 <= y1, not {self}")

    def overlaps(self, other: Box) -> bool:
        """Whether the two boxes share positive area: edges or corners that only touch do not count."""
        return (min(self.x1, other.x1) > max(self.x0, other.x0)
                and min(self.y1, other.y1) > max(self.y0, other.y0))


def corridor(scan_xy: np.ndarray, radius: float) -> Box:
    """The box a scan occupies: its waypoints' x, y ((N, 2), m) bounded and grown by the footprint `radius` (m)."""
    xy = np.asarray(scan_xy, dtype=float)
    if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) == 0:
        raise UserError(f"a scan's corridor needs an (N, 2) array of x, y with N >= 1, not shape {xy.shape}")
    if not np.isfinite(xy).all():
        raise UserError("a scan's corridor needs finite x, y")
    if not (math.isfinite(radius) and radius >= 0):
        raise UserError(f"a corridor's radius is a finite distance >= 0 m, not {radius}")
    (x0, y0), (x1, y1) = xy.min(axis=0), xy.max(axis=0)
    return Box(float(x0) - radius, float(y0) - radius, float(x1) + radius, float(y1) + radius)


@dataclass(frozen=True)
class Mission:
    """One row's scan: how long it flies (s, home to home) and the corridor its scan occupies."""

    row: int
    duration_s: float
    corridor: Box

    def __post_init__(self) -> None:
        # Checked here so that no mission the scheduler sees can put a bad number into fleet.json.
        if isinstance(self.row, bool) or not isinstance(self.row, int) or not 0 <= self.row < MAX_TABLES:
            raise UserError(f"a mission's row is a whole number in [0, {MAX_TABLES}), not {self.row!r}")
        if not (math.isfinite(self.duration_s) and 0 <= self.duration_s <= MAX_TIME):
            raise UserError(f"row {self.row}: a mission's duration is finite, in [0, {MAX_TIME:g}] s, "
                            f"not {self.duration_s}")


def _earliest(ready: float, duration: float, busy: list[tuple[float, float]]) -> float:
    """The earliest start >= `ready` at which [start, start + duration) meets none of the `busy` intervals.

    The intervals sorted by start are met in one sweep: an interval that overlaps the current start forces it to that
    interval's end (every start before its end overlaps it too), and the start only grows, so the intervals passed stay
    clear of it. A mission of no duration meets nothing."""
    start = ready
    for begin, end in sorted(busy):
        if max(start, begin) < min(start + duration, end):
            start = end
    return start


def schedule(missions: Sequence[Mission], uavs: int) -> Schedule:
    """The missions shared among `uavs` UAVs by the rules of the module's docstring."""
    if isinstance(uavs, bool) or not isinstance(uavs, int) or not 1 <= uavs <= MAX_COUNT:
        raise UserError(f"a fleet has a whole number of UAVs in [1, {MAX_COUNT}], not {uavs!r}")
    rows = [mission.row for mission in missions]
    if len(set(rows)) != len(rows):
        twice = next(row for row in rows if rows.count(row) > 1)
        raise UserError(f"row {twice} has two missions; a row is scanned by one mission")
    # Only the first len(missions) UAVs can ever be chosen: an idle UAV is free at 0 and ties go to the lowest index.
    free = [0.0] * min(uavs, len(missions))  # when each UAV's last flight ends
    flights: list[Flight] = []
    for mission in missions:
        busy = [(flight.start_s, flight.end_s) for flight, earlier in zip(flights, missions)
                if earlier.corridor.overlaps(mission.corridor)]
        duration = float(mission.duration_s)  # a numpy number would fail the file model's strict floats
        starts = [_earliest(ready, duration, busy) for ready in free]
        uav = starts.index(min(starts))
        start = starts[uav]
        end = start + duration
        if end > MAX_TIME:
            raise UserError(f"row {mission.row}: the missions would end at {end:g} s, beyond the {MAX_TIME:g} s "
                            "a run's times allow")
        free[uav] = end
        flights.append(Flight(uav=uav, row=mission.row, start_s=start, end_s=end))
    return Schedule(uavs=uavs, flights=flights, makespan_s=max(free, default=0.0))
