"""Procedural sweet-pepper plants: stem, branches, leaves, flowers and hanging fruit.

The fruit are placed first, because they are what the whole pipeline counts: each
one is sampled on its side of the row until it fits inside the plant's box, clear
of the pot, the stem and every other pepper (bounding spheres plus a gap), and
then gets a peduncle that hangs it from the stem. Leaves and flowers grow around
them and are resampled when they would cut into a fruit or leave the box, so the
box in `scene.json` is a true bound of the plant and the physics volume is honest.
"""

from __future__ import annotations

import math

import numpy as np

from renderloop.config import RIPE_COLORS, PepperConfig, PlantConfig
from renderloop.scene import meshes
from renderloop.scene.model import Box, Flower, Leaf, Pepper, Plant, Pot, Tube

PEPPER_GAP = 0.005  # m between the bounding spheres of two peppers
STEM_CLEARANCE = 0.015  # m between a pepper and the stem axis, beyond the stem radius and its wiggle
SOIL_DEPTH = 0.02  # soil surface below the pot rim, m (as meshes.pot draws it)
PLACEMENT_ATTEMPTS = 400

BASE_RGB = {
    "red": (0.55, 0.03, 0.02),
    "yellow": (0.85, 0.62, 0.04),
    "orange": (0.90, 0.33, 0.03),
    "green": (0.10, 0.33, 0.05),
}
LEAF_RGB = (0.10, 0.32, 0.06)  # each leaf's colour is this times a uniform draw in [0.75, 1.25] per channel


class PepperFitError(Exception):
    """The configured number and size of peppers does not fit on one side of the plant."""


def _round(values: np.ndarray | float) -> tuple[float, ...] | float:
    """Micrometre precision keeps scene.json readable and its bytes stable."""
    if np.ndim(values) == 0:
        return round(float(values), 6)
    return tuple(round(float(v), 6) for v in values)


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def _on_polyline(points: np.ndarray, fraction: float) -> np.ndarray:
    """Point at `fraction` of the arc length of a polyline."""
    lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
    target = fraction * lengths.sum()
    cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
    index = min(int(np.searchsorted(cumulative, target, side="right")) - 1, len(lengths) - 1)
    t = (target - cumulative[index]) / lengths[index]
    return points[index] + t * (points[index + 1] - points[index])


class PlantGrower:
    """Grows one plant in its slot; every random draw comes from the generator it is given."""

    def __init__(self, rng: np.random.Generator, config: PlantConfig, position: tuple[float, float, float]):
        self.rng = rng
        self.config = config
        self.base = np.asarray(position, dtype=float)
        half_x, half_y, height = config.volume[0] / 2, config.volume[1] / 2, config.volume[2]
        self.pot_top = self.base[2] + config.pot.height
        self.box_min = np.array([self.base[0] - half_x, self.base[1] - half_y, self.base[2]])
        self.box_max = np.array([self.base[0] + half_x, self.base[1] + half_y, self.pot_top + height])
        self.stem = self._grow_stem()
        self.peppers: list[dict] = []

    def uniform(self, bounds: tuple[float, float]) -> float:
        return float(self.rng.uniform(bounds[0], bounds[1]))

    def integer(self, bounds: tuple[int, int]) -> int:
        return int(self.rng.integers(bounds[0], bounds[1] + 1))

    def _inside(self, vertices: np.ndarray, margin: float = 0.0) -> bool:
        return bool(np.all(vertices >= self.box_min + margin) and np.all(vertices <= self.box_max - margin))

    def _clear_of_peppers(self, vertices: np.ndarray) -> bool:
        for pepper in self.peppers:
            if np.min(np.linalg.norm(vertices - pepper["center"], axis=1)) < pepper["radius"]:
                return False
        return True

    def _grow_stem(self) -> np.ndarray:
        height = self.uniform((0.8, 0.95)) * self.config.volume[2]
        heights = np.linspace(self.pot_top - SOIL_DEPTH, self.pot_top + height, 6)
        wiggle = np.clip(np.cumsum(self.rng.normal(0.0, 0.004, size=(6, 2)), axis=0), -0.01, 0.01)
        wiggle[0] = 0.0
        return np.column_stack([self.base[0] + wiggle[:, 0], self.base[1] + wiggle[:, 1], heights])

    def _stem_point_at(self, z: float) -> np.ndarray:
        z = float(np.clip(z, self.stem[0, 2], self.stem[-1, 2]))
        return np.array([np.interp(z, self.stem[:, 2], self.stem[:, i]) for i in range(2)] + [z])

    # fruit -------------------------------------------------------------------------------

    def place_pepper(self, side: int, config: PepperConfig, color: str) -> dict:
        """Sample one pepper on `side` (-1 left, +1 right) that clears everything placed so far."""
        half = (self.box_max - self.box_min)[:2] / 2
        for _ in range(PLACEMENT_ATTEMPTS):
            length = self.uniform(config.length)
            width = length * self.uniform(config.width_ratio)
            lobes = self.integer(config.lobes)
            lobe_depth = self.uniform(config.lobe_depth)
            tilt, azimuth = self.uniform((0.0, config.max_tilt)), self.uniform((0.0, 2 * math.pi))
            axis = np.array([math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), -math.cos(tilt)])
            twist = self.uniform((0.0, 2 * math.pi))
            shape = meshes.pepper(np.zeros(3), axis, length, width, lobes, lobe_depth, twist=twist)
            radius = float(np.max(np.linalg.norm(shape.vertices, axis=1)))
            reach_xy = float(np.max(np.linalg.norm(shape.vertices[:, :2], axis=1)))
            min_dx = reach_xy + self.config.stem_radius + STEM_CLEARANCE
            low_z, high_z = self.pot_top + radius + 0.02, self.box_max[2] - radius - 0.04
            if min_dx > half[0] - radius or radius > half[1] or low_z > high_z:
                continue
            center = self.base + np.array(
                [side * self.uniform((min_dx, half[0] - radius)), self.uniform((-(half[1] - radius), half[1] - radius)), 0.0]
            )
            center[2] = self.uniform((low_z, high_z))
            if any(np.linalg.norm(center - p["center"]) < radius + p["radius"] + PEPPER_GAP for p in self.peppers):
                continue
            pepper = dict(
                center=center, radius=radius, length=length, width=width, lobes=lobes, lobe_depth=lobe_depth,
                axis=axis, twist=twist, color=color, peduncle=self._peduncle(center, axis, length),
            )
            self.peppers.append(pepper)
            return pepper
        raise PepperFitError

    def _peduncle(self, center: np.ndarray, axis: np.ndarray, length: float) -> np.ndarray:
        top = center - axis * (length / 2)
        above = top + np.array([0.0, 0.0, self.uniform((0.012, 0.025))])
        on_stem = self._stem_point_at(above[2] + self.uniform((0.02, 0.06)))
        arc = (on_stem + above) / 2 + np.array([0.0, 0.0, 0.015])
        return np.vstack([on_stem, arc, above, top])

    # foliage -----------------------------------------------------------------------------

    def grow_branches(self) -> list[np.ndarray]:
        branches = []
        half = float(min(self.box_max[:2] - self.box_min[:2])) / 2
        for _ in range(self.integer(self.config.branches)):
            for _attempt in range(12):
                start = _on_polyline(self.stem, self.uniform((0.25, 0.75)))
                azimuth = self.uniform((0.0, 2 * math.pi))
                outward = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
                reach, rise = self.uniform((0.06, half - 0.05)), self.uniform((0.03, 0.1))
                points = np.array([start + outward * reach * f + np.array([0, 0, rise * f**0.7]) for f in (0.0, 0.35, 0.7, 1.0)])
                along = np.array([_on_polyline(points, f) for f in np.linspace(0.0, 1.0, 12)])
                if self._clear_of_peppers(along):
                    branches.append(points)
                    break
        return branches

    def grow_leaves(self, branches: list[np.ndarray]) -> list[Leaf]:
        leaves = []
        for _ in range(self.integer(self.config.leaves)):
            for _attempt in range(12):
                holder = branches[self.integer((0, len(branches) - 1))] if branches and self.rng.random() < 0.5 else self.stem
                base = _on_polyline(holder, self.uniform((0.2, 1.0)))
                azimuth, elevation = self.uniform((0.0, 2 * math.pi)), self.uniform((-0.2, 0.7))
                direction = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation)])
                up = _unit(np.array([*self.rng.normal(0.0, 0.3, size=2), 1.0]))
                length = self.uniform(self.config.leaf_length)
                params = dict(
                    length=length, width=length * self.uniform(self.config.leaf_width_ratio),
                    curvature=self.uniform(self.config.leaf_curvature), fold=self.uniform((0.0, 0.5)),
                    twist=self.uniform((-0.5, 0.5)),
                )
                blade = meshes.leaf(base, direction, up, **params)
                if self._inside(blade.vertices) and np.all(blade.vertices[:, 2] > self.pot_top) and self._clear_of_peppers(blade.vertices):
                    rgb = np.clip(np.array(LEAF_RGB) * self.rng.uniform(0.75, 1.25, size=3), 0.0, 1.0)
                    leaves.append(Leaf(base=_round(base), direction=_round(direction), up=_round(up), rgb=_round(rgb),
                                       **{k: _round(v) for k, v in params.items()}))
                    break
        return leaves

    def grow_flowers(self, branches: list[np.ndarray]) -> list[Flower]:
        anchors = [branch[-1] for branch in branches] + [self.stem[-1]]
        flowers = []
        for _ in range(self.integer(self.config.flowers)):
            for _attempt in range(12):
                anchor = anchors[self.integer((0, len(anchors) - 1))]
                center = anchor + self.rng.normal(0.0, 0.015, size=3)
                azimuth, elevation = self.uniform((0.0, 2 * math.pi)), self.uniform((0.2, 1.2))
                normal = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation)])
                radius = self.uniform((0.008, 0.014))
                petals = meshes.flower(center, normal, radius)
                if self._inside(petals.vertices) and self._clear_of_peppers(petals.vertices):
                    flowers.append(Flower(center=_round(center), normal=_round(normal), radius=_round(radius)))
                    break
        return flowers


def pepper_rgb(rng: np.random.Generator, color: str) -> np.ndarray:
    return np.clip(np.array(BASE_RGB[color]) * rng.uniform(0.85, 1.15, size=3), 0.0, 1.0)


def place_fruit(
    grower: PlantGrower, plant_id: int, peppers_per_side: tuple[int, int], first_pepper_id: int
) -> list[Pepper]:
    """The fruit of a plant, (left, right) = `peppers_per_side`, ids counting from `first_pepper_id`: every style
    places them so (the same draws in the same order), so one seed gives the same fruit whatever the style."""
    rng, config = grower.rng, grower.config
    fruit_config = config.peppers
    names = list(fruit_config.colors)
    weights = np.array([fruit_config.colors[name] for name in names], dtype=float)
    peppers = []
    for side, count in zip((-1, 1), peppers_per_side):
        for _ in range(count):
            color = names[int(rng.choice(len(names), p=weights / weights.sum()))]
            fruit = grower.place_pepper(side, fruit_config, color)
            peppers.append(
                Pepper(
                    id=first_pepper_id + len(peppers), plant=plant_id, side="left" if side < 0 else "right",
                    center=_round(fruit["center"]),
                    radius=math.ceil(fruit["radius"] * 1e6) / 1e6 + 2e-6,
                    color=color, ripe=color in RIPE_COLORS, rgb=_round(pepper_rgb(rng, color)),
                    length=_round(fruit["length"]), width=_round(fruit["width"]), lobes=fruit["lobes"],
                    lobe_depth=_round(fruit["lobe_depth"]), axis=_round(fruit["axis"]), twist=_round(fruit["twist"]),
                    peduncle=Tube(points=[_round(p) for p in fruit["peduncle"]], radius=0.004),
                )
            )
    return peppers


def grow_plant(
    rng: np.random.Generator,
    config: PlantConfig,
    plant_id: int,
    row: int,
    position: tuple[float, float, float],
    peppers_per_side: tuple[int, int],
    first_pepper_id: int,
) -> tuple[Plant, list[Pepper]]:
    """One plant with `peppers_per_side` = (left, right) fruit, ids counting from `first_pepper_id`."""
    grower = PlantGrower(rng, config, position)
    peppers = place_fruit(grower, plant_id, peppers_per_side, first_pepper_id)
    branches = grower.grow_branches()
    plant = Plant(
        id=plant_id, row=row, position=_round(grower.base),
        bounds=Box(min=_round(grower.box_min), max=_round(grower.box_max)),
        bearing=sum(peppers_per_side) > 0,
        pot=Pot(radius_top=config.pot.radius_top, radius_bottom=config.pot.radius_bottom, height=config.pot.height),
        stem=Tube(points=[_round(p) for p in grower.stem], radius=config.stem_radius),
        branches=[Tube(points=[_round(p) for p in branch], radius=round(0.6 * config.stem_radius, 6)) for branch in branches],
        leaves=grower.grow_leaves(branches),
        flowers=grower.grow_flowers(branches),
    )
    return plant, peppers
