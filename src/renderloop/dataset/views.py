"""Random camera views of plants: where a scan camera could be, and wider.

The flown camera sees a plant from 0.3-0.5 m in its aisle; training views spread
distance, height, bearing and aim around that (and add a little roll, which a
tilting UAV gives its camera), so the detector meets fruit at every size, at the
image edges and half hidden, never only centred. A view is redrawn when the camera
would sit inside a plant's box, a table or below the table top, or inside or behind
an obstacle (the training set's standing boards). Close views look at one fruit from
a hand's breadth to half a metre, from any side, as a close scan or a photo does; views of picked fruit
(dataset/picked.py) look down at one from around it, as at a crate or a table.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from renderloop.config.dataset import DISTANCE  # m from the plant's axis; drawn closer more often, as scans are
from renderloop.robot.kinematics import look_at
from renderloop.scene.model import Pepper, Scene
from renderloop.scene.objects import Box

BEARING = math.radians(60.0)  # spread around the row's normal
HEIGHT = (-0.15, 0.35)  # m about the canopy centre
TALL = 1.0  # m: a canopy taller than this is seen at every height of it, up to TALL_HEIGHT of it from its centre
TALL_HEIGHT = 0.4
MAX_UPWARD = math.radians(20.0)  # scans look level or down; a little up is allowed
AIM = 0.3  # fraction of the canopy box the aim point may leave its centre by
ROLL = math.radians(8.0)
CLEARANCE = 0.05  # m between the camera and any plant box or table
MAX_TRIES = 200
# A close view looks at one fruit from a hand's breadth to half a metre, from any side and height, rolled as a
# hand-held camera is: the fruit fills a tenth to most of the frame, as in a close scan or a photo.
CLOSE_DISTANCE = (0.12, 0.5)  # m from the fruit's centre
CLOSE_ELEVATION = math.radians(60.0)  # up to this far above (or a third of it below) the fruit
CLOSE_BEARING = math.radians(80.0)  # spread around the direction from the plant's axis out to the fruit
CLOSE_ROLL = math.radians(35.0)
CLOSE_AIM = 0.25  # of the distance: the aim point's spread about the fruit's centre
PICKED_ELEVATION = (math.radians(20.0), math.radians(85.0))  # a picked fruit is seen from this far above it


def _roll(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _through(start: np.ndarray, end: np.ndarray, obstacle: Box) -> bool:
    """Whether the segment from `start` to `end` meets the box (grown by CLEARANCE): the slab test."""
    low = np.asarray(obstacle.center) - obstacle.half - CLEARANCE
    high = np.asarray(obstacle.center) + obstacle.half + CLEARANCE
    step = end - start
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (low - start) / step, (high - start) / step
    inside = (start >= low) & (start <= high)
    parallel = step == 0
    if np.any(parallel & ~inside):
        return False
    near = np.where(parallel, -np.inf, np.minimum(t0, t1)).max()
    far = np.where(parallel, np.inf, np.maximum(t0, t1)).min()
    return bool(near <= far and far >= 0.0 and near <= 1.0)


def _on_table(scene: Scene, position: np.ndarray) -> bool:
    for row in scene.rows:
        center, size = np.asarray(row.table.center), np.asarray(row.table.size)
        half = size / 2 + CLEARANCE
        if np.all(np.abs(position[:2] - center[:2]) <= half[:2]) and position[2] <= size[2] + CLEARANCE:
            return True
    return False


def _blocked(scene: Scene, position: np.ndarray) -> bool:
    return any(plant.bounds.contains(tuple(position), CLEARANCE) for plant in scene.plants) or _on_table(scene, position)


def _rolled(camera: np.ndarray, target: np.ndarray, roll: float) -> np.ndarray:
    pose = look_at(camera, target)
    pose[:3, :3] = pose[:3, :3] @ _roll(roll)
    return pose


def random_view(scene: Scene, rng: np.random.Generator, distance_range: tuple[float, float] = DISTANCE,
                obstacles: Sequence[Box] = ()) -> np.ndarray:
    """T_world_optical of one random view of a random plant, `distance_range` m (horizontal) from its axis,
    neither inside nor looking through any of the `obstacles`."""
    for _ in range(MAX_TRIES):
        plant = scene.plants[int(rng.integers(len(scene.plants)))]
        low, high = np.asarray(plant.bounds.min), np.asarray(plant.bounds.max)
        canopy_low = np.array([low[0], low[1], plant.position[2] + plant.pot.height])
        center, size = (canopy_low + high) / 2, high - canopy_low
        side = 0.0 if rng.random() < 0.5 else math.pi  # rows run along y: look from +x or -x
        bearing = side + rng.uniform(-BEARING, BEARING)
        distance = distance_range[0] + (distance_range[1] - distance_range[0]) * rng.random() ** 2
        camera = np.array([plant.position[0] + distance * math.cos(bearing), plant.position[1] + distance * math.sin(bearing),
                           center[2] + (rng.uniform(-TALL_HEIGHT, TALL_HEIGHT) * size[2] if size[2] > TALL
                                        else rng.uniform(*HEIGHT))])
        if _blocked(scene, camera):
            continue
        target = center + rng.uniform(-AIM, AIM, 3) * size
        if target[2] - camera[2] > math.tan(MAX_UPWARD) * math.hypot(*(target[:2] - camera[:2])):
            continue
        if any(_through(camera, target, obstacle) for obstacle in obstacles):
            continue
        return _rolled(camera, target, rng.uniform(-ROLL, ROLL))
    raise RuntimeError("no unobstructed camera position found around the plants")


def close_view(scene: Scene, rng: np.random.Generator, obstacles: Sequence[Box] = (), clip_reach: float = 0.0) -> np.ndarray:
    """T_world_optical of a view of one random fruit from close by (CLOSE_DISTANCE); the camera may be among the
    plant's leaves, never in a table, an obstacle or looking through one, nor within `clip_reach` m (how far the near
    clip plane reaches from the camera) of any fruit's bounding sphere: the clip would cut that fruit open, and its
    inside would be rendered."""
    centres = np.array([pepper.center for pepper in scene.peppers])
    keep_out = np.array([pepper.radius for pepper in scene.peppers]) + clip_reach
    for _ in range(MAX_TRIES):
        pepper = scene.peppers[int(rng.integers(len(scene.peppers)))]
        plant = next(p for p in scene.plants if p.id == pepper.plant)
        center = np.asarray(pepper.center)
        out = center[:2] - np.asarray(plant.position[:2])
        heading = math.atan2(out[1], out[0]) + rng.uniform(-CLOSE_BEARING, CLOSE_BEARING)
        elevation = rng.uniform(-CLOSE_ELEVATION / 3, CLOSE_ELEVATION)
        distance = rng.uniform(*CLOSE_DISTANCE)
        camera = center + distance * np.array([math.cos(elevation) * math.cos(heading),
                                               math.cos(elevation) * math.sin(heading), math.sin(elevation)])
        target = center + rng.uniform(-CLOSE_AIM, CLOSE_AIM, 3) * distance
        if _on_table(scene, camera) or camera[2] < CLEARANCE or any(_through(camera, target, o) for o in obstacles) \
                or np.any(np.linalg.norm(centres - camera, axis=1) < keep_out):
            continue
        return _rolled(camera, target, rng.uniform(-CLOSE_ROLL, CLOSE_ROLL))
    raise RuntimeError("no unobstructed close view of a fruit found")


def _over_rim(camera: np.ndarray, center: np.ndarray, crate: Box) -> bool:
    """Whether the sight line from a fruit at `center` to `camera` leaves `crate` through its open top (or the fruit
    is not in it): a crate's walls hide the fruit in it from the side."""
    low, high = np.asarray(crate.center) - crate.half, np.asarray(crate.center) + crate.half
    if np.any(center[:2] < low[:2]) or np.any(center[:2] > high[:2]) or not low[2] <= center[2] <= high[2]:
        return True
    if camera[2] <= high[2]:
        return False
    xy = center[:2] + (high[2] - center[2]) / (camera[2] - center[2]) * (camera[:2] - center[:2])
    return bool(np.all(xy > low[:2]) and np.all(xy < high[:2]))


def picked_view(scene: Scene, fruit: Sequence[Pepper], rng: np.random.Generator, boards: Sequence[Box] = (),
                crates: Sequence[Box] = (), clip_reach: float = 0.0) -> np.ndarray:
    """T_world_optical of a view of one random picked fruit of `fruit` from CLOSE_DISTANCE, from any bearing and
    PICKED_ELEVATION above it; the camera inside neither a plant's box, a table, the workstation, a board nor a
    crate, looking at the fruit through neither a board nor its crate's wall, and clear of every fruit by
    `clip_reach` as `close_view`'s is."""
    every = [*scene.peppers, *fruit]
    centres = np.array([pepper.center for pepper in every])
    keep_out = np.array([pepper.radius for pepper in every]) + clip_reach
    station = Box.sized("workstation", scene.workstation.center, scene.workstation.size)
    solid = [*boards, *crates, station]
    for _ in range(MAX_TRIES):
        center = np.asarray(fruit[int(rng.integers(len(fruit)))].center)
        heading, elevation = rng.uniform(0.0, 2 * math.pi), rng.uniform(*PICKED_ELEVATION)
        distance = rng.uniform(*CLOSE_DISTANCE)
        camera = center + distance * np.array([math.cos(elevation) * math.cos(heading),
                                               math.cos(elevation) * math.sin(heading), math.sin(elevation)])
        target = center + rng.uniform(-CLOSE_AIM, CLOSE_AIM, 3) * distance
        if _blocked(scene, camera) or any(_through(camera, camera, box) for box in solid) \
                or any(_through(camera, target, board) for board in boards) \
                or not all(_over_rim(camera, center, crate) for crate in crates) \
                or np.any(np.linalg.norm(centres - camera, axis=1) < keep_out):
            continue
        return _rolled(camera, target, rng.uniform(-CLOSE_ROLL, CLOSE_ROLL))
    raise RuntimeError("no unobstructed view of a picked fruit found")
