"""What a camera at given positions can see of a scene: the rule by which a renderer builds only that.

A commercial compartment holds hundreds of plants and the film greenhouse round it hundreds more, while a camera
that flies along one row sees, within its far clip, the plants near it. A renderer that is told where its camera
will be (the render stage knows every pose from groundtruth.txt) builds the view of `visible_scene`: the scene
with only the scanned plants (and their fruit) and the neighbouring rows' plants whose box comes within reach of
some camera position: as far as the frame's corners reach to the far clip's plane (`farthest_seen`). A plant's box holds its leaves, stems, fruit and, in a film greenhouse, its strings
up to the crop wire. The static parts (floor, walls, tables, benches, the greenhouse's structure, traps) stay:
they are a few shapes.

Whatever lies farther from every camera than the far clip is no pixel's first hit, so the masks and the ids of the
fruit built stay the whole scene's; only light that a dropped plant would have shaded or bounced can differ. A
renderer that names its shadow-casting light (the raster view's sun) also keeps the plants whose shadow falls
within the far clip, and draws the whole scene's colours; its depth differs in the last bit of float32 where a
mesh merges several plants' parts (the copies' fruit stalks and calyces), which MuJoCo stores about the centre of
what was merged. Cycles' sun can stand low enough for a shadow to cross the compartment, and its indirect rays
are not clipped, so a dropped plant's shade and bounce light are missing from its frame: a small share of a
pixel's light at 5 m or more.

The scene returned is for views only: it keeps each plant's id, so its plant list is no longer indexed by id
(`Scene.plant` is not asked of it; `greenhouse_objects` never asks). The truth (scene.json) stays whole.

Numpy only, so any process can cull.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from renderloop.scene.model import Pepper, Plant, Scene, placement

__all__ = ["farthest_seen", "plant_box", "visible_scene"]


CHUNK = 2_000_000  # camera positions times plants measured at once: tens of MB of distances


def farthest_seen(far: float, width: int, height: int, fx: float, fy: float, cx: float, cy: float) -> float:
    """How far from the camera a point it sees can be: the far clip is a plane (planar depth), so the frame's corner
    rays reach beyond it by the secant of their angle off the optical axis."""
    x = max(abs(-0.5 - cx), abs(width - 0.5 - cx)) / fx
    y = max(abs(-0.5 - cy), abs(height - 0.5 - cy)) / fy
    return float(far * np.sqrt(1.0 + x * x + y * y))


def plant_box(plant: Plant, peppers: Iterable[Pepper], top: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Low and high corners of a box that holds everything drawn of `plant` (in its own frame for a prototype): its
    bounds, its fruit (centre +- length) and its strings up to height `top` (None: no strings drawn)."""
    low, high = np.array(plant.bounds.min, dtype=float), np.array(plant.bounds.max, dtype=float)
    for pepper in peppers:
        centre, size = np.asarray(pepper.center, dtype=float), float(pepper.length)
        low, high = np.minimum(low, centre - size), np.maximum(high, centre + size)
    if top is not None:
        high[2] = max(high[2], top)
    return low, high


def _moved(box: tuple[np.ndarray, np.ndarray], transform: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The axis-aligned box round `box` under the 4x4 rigid map `transform`."""
    low, high = box
    corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])])
    moved = corners @ transform[:3, :3].T + transform[:3, 3]
    return moved.min(axis=0), moved.max(axis=0)


def _with_shadow(box: tuple[np.ndarray, np.ndarray], light: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """`box` and the floor it shades under a light travelling along `light` (None: no shadows): a renderer whose light
    casts shadows from everything it built needs what shades a point it sees as well."""
    if light is None:
        return box
    low, high = box
    shift = np.array([*(np.asarray(light[:2], dtype=float) / -float(light[2]) * high[2]), 0.0])  # the top's, on z = 0
    low, high = np.minimum(low, low + shift), np.maximum(high, high + shift)
    low[2] = min(low[2], 0.0)
    return low, high


def _near(lows: np.ndarray, highs: np.ndarray, positions: np.ndarray, far: float) -> np.ndarray:
    """Which boxes come within `far` of one of the positions (the distance to a box: 0 inside it)."""
    near = np.zeros(len(lows), dtype=bool)
    step = max(1, CHUNK // len(positions))
    for start in range(0, len(lows), step):
        low, high = lows[start:start + step, None], highs[start:start + step, None]
        gap = np.maximum(np.maximum(low - positions[None], positions[None] - high), 0.0)
        near[start:start + step] = (np.einsum("bpi,bpi->bp", gap, gap) <= far * far).any(axis=1)
    return near


def visible_scene(scene: Scene, positions: np.ndarray | None, far: float, light: np.ndarray | None = None) -> Scene:
    """`scene` with only the plants (scanned, with their fruit, and neighbouring) whose box comes within `far` (m; a
    camera's: `farthest_seen`) of one of the camera `positions` ((N, 3), m); `positions` None: the scene as it is. `light`: the direction a light
    that casts shadows travels (z < 0), whose shadows a plant's box then takes in."""
    if light is not None and not light[2] < 0:
        raise ValueError(f"visible_scene: a light travelling along {list(light)} never reaches the floor")
    if positions is None:
        return scene
    positions = np.asarray(positions, dtype=float).reshape(-1, 3)
    if not len(positions):
        raise ValueError("visible_scene: no camera positions to cull for")
    environment = scene.environment
    top = None if environment is None else float(environment.wire_height)

    boxes = []
    for plant in scene.plants:
        prototype = scene.prototype_of(plant)
        if prototype is None:
            boxes.append(_with_shadow(plant_box(plant, scene.peppers_of(plant.id), top), light))
        else:  # a copy's fruit are its sites' scaled by at most 1 about their stalk ends: the prototype's box holds them
            box = _moved(plant_box(prototype.plant, prototype.fruit, top), placement(plant, prototype.plant))
            boxes.append(_with_shadow(box, light))
    kept = _near(*(np.array(corner).reshape(-1, 3) for corner in zip(*boxes)), positions, far) if boxes else []
    plants = [plant for plant, keep in zip(scene.plants, kept) if keep]
    ids = {plant.id for plant in plants}
    update: dict = {"plants": plants, "peppers": [pepper for pepper in scene.peppers if pepper.plant in ids]}

    if environment is not None and environment.plants:
        # a neighbouring copy is its prototype (grown with its pot's base at x = y = 0) turned by its yaw about z
        # and moved across to its position, as scene/objects.py stands it
        own = [plant_box(prototype.plant, prototype.fruit, top) for prototype in environment.prototypes]
        boxes = []
        for copy in environment.plants:
            c, s = np.cos(copy.yaw), np.sin(copy.yaw)
            transform = np.eye(4)
            transform[:2, :2] = [[c, -s], [s, c]]
            transform[:2, 3] = copy.position[:2]
            boxes.append(_with_shadow(_moved(own[copy.prototype], transform), light))
        near = _near(*(np.array(corner) for corner in zip(*boxes)), positions, far)
        update["environment"] = environment.model_copy(
            update={"plants": [copy for copy, keep in zip(environment.plants, near) if keep]})
    return scene.model_copy(update=update)
