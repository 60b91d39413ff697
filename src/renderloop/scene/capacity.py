"""Whether this machine can hold a greenhouse: memory and disk estimated from the config before anything is grown.

A compartment of thousands of plants, each grown in its place with its hundreds of leaves, or a run directory on a
nearly full disk, would fail minutes into the scene stage (out of memory, or a half-written disk). The scene stage
asks here first and refuses in one line with the estimate. The figures are upper bounds fitted to
`benchmarks/scene_scaling.py` (1000 'highwire' plants as copies of 8 prototypes: 361 MB peak, 5.5 MB of scene.json).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.io.disk import free_bytes

__all__ = ["Estimate", "available_memory", "check_capacity", "estimate"]

BASE_MEMORY = 300e6  # bytes: the interpreter with numpy, pydantic, MuJoCo and matplotlib, and the top view's canvas
LEAF_MEMORY = 6e3  # bytes a grown leaf holds while the scene is built: its model, its checks' arrays, its JSON
FRUIT_MEMORY = 6e3  # bytes a fruit holds: its model, its patch in the top view, its JSON
PLANT_MEMORY = 6e3  # bytes a plant holds beside its leaves and fruit: its model, its geoms in world.xml
LEAF_BYTES = 450  # bytes of scene.json a leaf takes
FRUIT_BYTES, COPY_FRUIT_BYTES = 750, 200  # of a grown plant's fruit, of a copy's (its own draws only)
PLANT_BYTES = 400  # of scene.json a plant takes beside its leaves and fruit
WORLD_BYTES = 700  # of world.xml a plant takes (its pot, canopy and strings)
NEIGHBOURS = 4  # plants the film greenhouse grows for its neighbouring rows when the scene has no library
DISK_MARGIN = 2.0  # the scene stage writes each file beside its old one before replacing it


@dataclass(frozen=True)
class Estimate:
    plants: int
    grown: int
    fruit: int
    memory: float  # bytes
    disk: float  # bytes


def estimate(config: Config) -> Estimate:
    """Upper bounds of what building the scene of `config` takes: peak memory and the bytes its files take."""
    greenhouse, plants = config.greenhouse, config.plants
    total = len(greenhouse.tables) * greenhouse.plants_per_table
    copies = total > plants.prototypes
    grown = min(total, plants.prototypes)
    if greenhouse.environment.kind == "film" and not copies:
        grown += NEIGHBOURS
    bearing = total if plants.bearing is None else min(plants.bearing, total)
    fruit = bearing * 2 * plants.peppers.per_side[1]
    leaves = grown * plants.most_leaves
    scene_bytes = leaves * LEAF_BYTES + fruit * (COPY_FRUIT_BYTES if copies else FRUIT_BYTES) + total * PLANT_BYTES
    memory = BASE_MEMORY + leaves * LEAF_MEMORY + fruit * FRUIT_MEMORY + total * PLANT_MEMORY
    return Estimate(total, grown, fruit, memory, DISK_MARGIN * (scene_bytes + total * WORLD_BYTES))


def available_memory() -> float:
    """Bytes of memory this machine can give a process now (MemAvailable), or its physical memory."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return float(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))


def check_capacity(config: Config, run_dir: Path, memory: float | None = None, disk: float | None = None) -> Estimate:
    """Refuse, in one line with the estimate, a greenhouse this machine cannot build: more memory than it has
    available (`memory`, bytes; default: now) or more disk than is free under `run_dir` (`disk`)."""
    need = estimate(config)
    memory = available_memory() if memory is None else memory
    disk = free_bytes(run_dir) if disk is None else disk
    size = (f"{need.plants} plants ({need.grown} grown, the rest copies; up to {need.fruit} fruit) need about "
            f"{need.memory / 1e9:.2f} GB of memory and {need.disk / 1e6:.0f} MB of disk")
    if need.memory > memory:
        raise UserError(f"greenhouse: {size}, but this machine has {memory / 1e9:.2f} GB available (fewer plants, "
                        f"greenhouse.plants_per_table, or fewer grown, plants.prototypes)")
    if need.disk > disk:
        raise UserError(f"greenhouse: {size}, but {disk / 1e6:.0f} MB are free under {run_dir}")
    return need
