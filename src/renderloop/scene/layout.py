"""Greenhouse floor plan: where the tables, their plant slots and the workstation stand.

Kept apart from plant growth so that the planner and tests can reason about the
layout without any randomness.
"""

from __future__ import annotations

from dataclasses import dataclass

from renderloop.config import GreenhouseConfig
from renderloop.errors import UserError


@dataclass(frozen=True)
class TableSlot:
    row: int
    center: tuple[float, float, float]
    size: tuple[float, float, float]
    plant_positions: list[tuple[float, float, float]]


def _footprint(center: tuple[float, float], size: tuple[float, float, float]) -> tuple[float, float, float, float]:
    return (center[0] - size[0] / 2, center[0] + size[0] / 2, center[1] - size[1] / 2, center[1] + size[1] / 2)


def _overlap(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> bool:
    return a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3]


def table_slots(greenhouse: GreenhouseConfig) -> list[TableSlot]:
    """One slot per table, in config order; plants spaced evenly along y, centred on the table."""
    size = greenhouse.table_size
    footprints = [_footprint(center, size) for center in greenhouse.tables]
    station = _footprint(greenhouse.workstation_center, greenhouse.workstation_size)
    for index, footprint in enumerate(footprints):
        if _overlap(footprint, station):
            raise UserError(f"greenhouse.tables: table {index} overlaps the workstation")
        for other in range(index):
            if _overlap(footprint, footprints[other]):
                raise UserError(f"greenhouse.tables: tables {other} and {index} overlap")
    count = greenhouse.plants_per_table
    slots = []
    for row, (x, y) in enumerate(greenhouse.tables):
        offsets = [(i - (count - 1) / 2) * greenhouse.plant_spacing for i in range(count)]
        slots.append(
            TableSlot(
                row=row,
                center=(x, y, size[2] / 2),
                size=size,
                plant_positions=[(x, y + offset, size[2]) for offset in offsets],
            )
        )
    return slots
