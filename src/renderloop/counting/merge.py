"""The count of a compartment from the counts of missions that each scanned some of its rows.

A mission of one row (`planner.row`) counts and scores that row alone (`renderloop.counting.summary`);
`merge_counts` puts the rows' `counts.json` together into the compartment's: every part's plants
and rows, the total recomputed from them as `summarise` computes it, the detections tallied over
the missions, and the total's interval from the rows' distributions convolved (the rows are
counted from different frames, so independent), which is what counting the rows together gives.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from renderloop.counting.summary import total_of
from renderloop.counting.uncertainty import central_interval, convolved
from renderloop.errors import UserError
from renderloop.rundir.models import Counts, DetectionTally


def _settings_differ(first: dict[str, Any], other: dict[str, Any]) -> str:
    """The first setting, by name, that two counts' settings disagree on."""
    for name in sorted(first.keys() | other.keys()):
        if first.get(name, "unset") != other.get(name, "unset"):
            return f"{name} {first.get(name, 'unset')!r} against {other.get(name, 'unset')!r}"
    return "none"


def _checked(parts: Sequence[Counts]) -> None:
    if not parts:
        raise UserError("merge_counts: no counts to merge")
    for index, part in enumerate(parts[1:], start=1):
        if part.settings != parts[0].settings:
            raise UserError(f"merge_counts: part {index} was counted with other settings than part 0 "
                            f"({_settings_differ(parts[0].settings, part.settings)})")
    for kind, entries in (("row", lambda part: part.rows), ("plant", lambda part: part.plants)):
        owner: dict[int, int] = {}
        for index, part in enumerate(parts):
            for entry in entries(part):
                if entry.id in owner:
                    raise UserError(f"merge_counts: {kind} {entry.id} is counted in part {owner[entry.id]} and in part {index}")
                owner[entry.id] = index


def _total_interval(parts: Sequence[Counts]) -> dict[str, Any] | None:
    """The central interval of the sum of every row's distribution, at the rows' level; None when a row has none."""
    rows = [row for part in parts for row in part.rows]
    if not rows or any(row.distribution is None or row.interval is None for row in rows):
        return None
    level = rows[0].interval.level
    low, high = central_interval(convolved(np.array(row.distribution, dtype=float) for row in rows), level)
    return {"low": low, "high": high, "level": level}


def merge_counts(parts: Sequence[Counts]) -> Counts:
    """The count of the rows of every part as one `counts.json`: each part the count of a mission over rows no other
    part counts, with the same counting settings (else a one-line UserError naming the row or the setting). Plants and
    rows sorted by id; the total as `summarise` makes it from them (the scan's misses only where every part knows its
    own), its interval from the rows' distributions (None when a row has none); the detections tallied over every
    part, so `frames` is the frames of all missions."""
    _checked(parts)
    plants = sorted((plant for part in parts for plant in part.plants), key=lambda plant: plant.id)
    rows = sorted((row for part in parts for row in part.rows), key=lambda row: row.id)
    misses = all(part.total.unseen is not None for part in parts)
    tally = {name: sum(getattr(part.detections, name) for part in parts) for name in DetectionTally.model_fields}
    return Counts.model_validate({
        "plants": [plant.model_dump() for plant in plants],
        "rows": [row.model_dump() for row in rows],
        "total": total_of([plant.model_dump() for plant in plants], _total_interval(parts), misses),
        "detections": tally,
        "settings": parts[0].settings,
    }, strict=False)
